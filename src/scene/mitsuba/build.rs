//! A scene from Mitsuba's tree of objects ([`super::xml`]): the sensor and its film and sampler,
//! the integrator's path length, shapes with their BSDFs and area emitters, shape groups and
//! their instances, and the other emitters. What is not read is one note naming the file and
//! line, and the render goes on with the fallback the note names (`docs/scene-format.md`,
//! "Mitsuba scenes").

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Affine2, DAffine3, DMat3, DMat4, DVec3, Vec2, Vec3, Vec3A};

use super::materials::{BlendMaterial, ConductorMaterial, DielectricMaterial, PlasticMaterial};
use super::props::Props;
use super::shapes::{self, RawMesh};
use super::xml::{Child, Object, Place, Resolver};
use crate::render::bsdf::microfacet::{Distribution, Microfacet};
use crate::scene::cutout::{Alpha, AlphaMode};
use crate::scene::environment::EnvironmentMap;
use crate::scene::image::Image;
use crate::scene::texture::{Sampling, Texture, Wrap};
use crate::scene::{
    Camera, FilmSettings, Geometry, Instance, Lens, Light, Maps, Material, Mesh, PixelFilter, RenderSettings,
    Scene, SceneError, Shape, Window,
};

/// Reads Mitsuba scene `path`, `-D` `overrides` first.
pub fn scene(path: &Path, overrides: &[(String, String)]) -> Result<Scene, SceneError> {
    let (root, resolver) = super::xml::read(path, overrides).map_err(|e| error(path, &e))?;
    let mut scene =
        Builder::new(path, &root, resolver).and_then(|b| b.build()).map_err(|e| error(path, &e))?;
    scene.parameters = overrides.to_vec();
    Ok(scene)
}

/// A message "file:line: what" as a scene error of that file and line.
fn error(path: &Path, message: &str) -> SceneError {
    // The place is everything before the first ":<digits>: ".
    let mut search = 0;
    while let Some(k) = message[search..].find(':') {
        let colon = search + k;
        let rest = &message[colon + 1..];
        let digits = rest.chars().take_while(char::is_ascii_digit).count();
        if digits > 0 && rest[digits..].starts_with(": ") {
            if let Ok(line) = rest[..digits].parse() {
                return SceneError::new(Path::new(&message[..colon]), Some(line), &rest[digits + 2..]);
            }
        }
        search = colon + 1;
    }
    let prefix = format!("{}: ", path.display());
    SceneError::new(path, None, message.strip_prefix(&prefix).unwrap_or(message))
}

/// The diffuse reflectance of a shape without a BSDF (Mitsuba's default `diffuse`).
const DEFAULT_REFLECTANCE: f64 = 0.5;
/// Mitsuba's default film size.
const DEFAULT_FILM: (u32, u32) = (768, 576);
/// Mitsuba's paths have no length limit by default (`max_depth` -1); lightsplit's are at most
/// this long, far past where Russian roulette ends them.
const UNLIMITED_DEPTH: u32 = 64;

/// Mitsuba's luminance of linear sRGB (its `luminance()`).
const MITSUBA_LUMINANCE: Vec3 = Vec3::new(0.212671, 0.715160, 0.072169);

/// How an image texture is read: as colour (8-bit images sRGB-decoded) or as data; and for a
/// scalar (`opacity`, `alpha`), reduced to its luminance in every channel, as Mitsuba's
/// `eval_1` reads a colour bitmap (its alpha channel dropped).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
enum Decode {
    Color,
    Data,
    Luminance { raw: bool },
}

/// What a shape group holds, in its own coordinates.
struct Group {
    parts: Vec<(Geometry, u32, Vec3, String)>,
}

struct Builder<'o> {
    path: PathBuf,
    resolver: Resolver,
    root: &'o Object,
    ids: HashMap<&'o str, &'o Object>,
    notes: Vec<String>,
    inputs: Vec<PathBuf>,
    materials: Vec<Material>,
    maps: Vec<Maps>,
    textures: Vec<Texture>,
    material_of: HashMap<*const Object, u32>,
    images: HashMap<(PathBuf, Decode), Arc<Image>>,
    shapes: Vec<Shape>,
    lights: Vec<Light>,
    objects: Vec<String>,
    /// The ids of the BSDFs that have one, by material.
    material_names: Vec<(u32, String)>,
    origin: DVec3,
    groups: HashMap<*const Object, Arc<Group>>,
    defaults: HashMap<bool, u32>,
}

impl<'o> Builder<'o> {
    fn new(path: &Path, root: &'o Object, resolver: Resolver) -> Result<Self, String> {
        let mut ids = HashMap::new();
        collect_ids(root, &mut ids)?;
        let inputs = resolver.files.clone();
        Ok(Builder {
            path: path.to_path_buf(),
            resolver,
            root,
            ids,
            notes: Vec::new(),
            inputs,
            materials: Vec::new(),
            maps: Vec::new(),
            textures: Vec::new(),
            material_of: HashMap::new(),
            images: HashMap::new(),
            shapes: Vec::new(),
            lights: Vec::new(),
            objects: Vec::new(),
            material_names: Vec::new(),
            origin: DVec3::ZERO,
            groups: HashMap::new(),
            defaults: HashMap::new(),
        })
    }

    fn note(&mut self, at: &Place, what: impl std::fmt::Display) {
        self.notes.push(format!("{at}: {what}"));
    }

    /// One note for each property `props` did not read.
    fn unread(&mut self, props: &Props) {
        let what = format!("<{} type=\"{}\">", props.object.tag, props.object.kind);
        for (name, at) in props.unread() {
            self.notes.push(format!("{at}: `{name}` of {what} is not read"));
        }
    }

    /// The object a child is, or the one its reference names.
    fn resolve(&self, child: &'o Child) -> Result<&'o Object, String> {
        match child {
            Child::Object(o) => Ok(o),
            Child::Ref { id, at, .. } => {
                self.ids.get(id.as_str()).copied().ok_or_else(|| format!("{at}: no object has the id `{id}`"))
            }
        }
    }

    /// The children of `object` (resolved) with tag `tag`.
    fn children_tagged(&self, object: &'o Object, tag: &str) -> Result<Vec<&'o Object>, String> {
        let mut out = Vec::new();
        for c in &object.children {
            let o = self.resolve(c)?;
            if o.tag == tag {
                out.push(o);
            }
        }
        Ok(out)
    }

    /// The child of `object` given the name `name`.
    fn named(&self, object: &'o Object, name: &str) -> Result<Option<&'o Object>, String> {
        for c in &object.children {
            let given = match c {
                Child::Object(o) => o.name.as_deref(),
                Child::Ref { name, .. } => name.as_deref(),
            };
            if given == Some(name) {
                return self.resolve(c).map(Some);
            }
        }
        Ok(None)
    }

    fn file(&mut self, props: &Props, name: &str) -> Result<PathBuf, String> {
        let file = props.string(name)?.ok_or_else(|| {
            format!("{}: <{} type=\"{}\"> has no `{name}`", props.at(), props.object.tag, props.object.kind)
        })?;
        let path = self.resolver.resolve(file);
        if !path.is_file() {
            return Err(format!("{}: `{file}` is not a file (resolved as {})", props.at(), path.display()));
        }
        if !self.inputs.contains(&path) {
            self.inputs.push(path.clone());
        }
        Ok(path)
    }

    fn build(mut self) -> Result<Scene, String> {
        let root = self.root;
        let sensor = self.children_tagged(root, "sensor")?;
        let (camera, film, seed, sampler_count) = match sensor.first() {
            Some(s) => self.sensor(s)?,
            None => return Err(format!("{}: the scene has no <sensor>", root.at)),
        };
        if sensor.len() > 1 {
            self.note(&sensor[1].at, "a second <sensor>: lightsplit renders through the first");
        }
        let max_depth = self.integrator()?;
        for child in &root.children {
            // References at the top level only name what is defined elsewhere.
            let Child::Object(o) = child else { continue };
            match o.tag.as_str() {
                "shape" if o.kind == "shapegroup" => {}
                "shape" => self.shape(o, None)?,
                // An area emitter given an id at the top is for the shapes that refer to it.
                "emitter" if o.kind == "area" && o.id.is_some() => {}
                "emitter" => self.emitter(o)?,
                "sensor" | "integrator" | "bsdf" | "texture" => {}
                "medium" => self
                    .note(&o.at, format!("<medium type=\"{}\"> is not read: no participating media", o.kind)),
                other => self.note(&o.at, format!("<{other}> is not read")),
            }
        }
        let mut film = film;
        film.spp = sampler_count;
        let mut camera = camera;
        camera.position = Vec3::ZERO;
        camera.look_at = (camera.look_at.as_dvec3()).as_vec3();
        if self.lights.is_empty() && !self.shapes.iter().any(Shape::is_emissive) {
            self.notes.push(format!("{}: the scene has no emitter: it renders black", self.path.display()));
        }
        let (maps, materials) = (self.maps, self.materials);
        Ok(Scene {
            path: self.path,
            inputs: self.inputs,
            origin: self.origin,
            camera,
            film,
            render: RenderSettings {
                max_depth,
                seed,
                sampler: Default::default(),
                light_sampler: Default::default(),
                guiding: Default::default(),
            },
            materials,
            shapes: self.shapes,
            lights: self.lights,
            objects: self.objects,
            material_names: self.material_names,
            filter: None,
            textures: self.textures,
            maps,
            notes: self.notes,
            parameters: Vec::new(),
            aovs: Vec::new(),
            light_groups: Default::default(),
        })
    }

    /// The camera (relative to the origin it sets: its position), the film, the seed and the
    /// samples per pixel.
    fn sensor(&mut self, s: &'o Object) -> Result<(Camera, FilmSettings, u64, u32), String> {
        let p = Props::new(s);
        if !matches!(s.kind.as_str(), "perspective" | "thinlens") {
            return Err(format!(
                "{}: <sensor type=\"{}\"> is not read; lightsplit reads `perspective` and `thinlens`",
                s.at, s.kind
            ));
        }
        let films = self.children_tagged(s, "film")?;
        let film = match films.first() {
            Some(f) => self.film(f)?,
            None => FilmSettings {
                pixel_filter: PixelFilter::Gaussian { stddev: 0.5 },
                ..FilmSettings::new(DEFAULT_FILM.0, DEFAULT_FILM.1, 1)
            },
        };
        // The view is the whole film's, whatever part of it the image is.
        let (width, height) =
            film.window.map_or((film.width, film.height), |w| (w.film_width, w.film_height));
        let samplers = self.children_tagged(s, "sampler")?;
        let (spp, seed) = match samplers.first() {
            Some(o) => {
                let sp = Props::new(o);
                let spp = sp.integer("sample_count", 4)?;
                let seed = sp.integer("seed", 0)?;
                if !matches!(
                    o.kind.as_str(),
                    "independent" | "stratified" | "multijitter" | "ldsampler" | "orthogonal"
                ) {
                    self.note(
                        &o.at,
                        format!("<sampler type=\"{}\"> is not known: lightsplit's own sampler", o.kind),
                    );
                }
                sp.skip("jitter");
                sp.skip("dimension");
                self.unread(&sp);
                let spp = u32::try_from(spp)
                    .ok()
                    .filter(|&n| n >= 1)
                    .ok_or_else(|| format!("{}: `sample_count` must be at least 1, not {spp}", o.at))?;
                (spp, seed.unsigned_abs())
            }
            None => (4, 0),
        };
        let t = p.transform("to_world")?;
        let position = t.transform_point3(DVec3::ZERO);
        let forward = t.transform_vector3(DVec3::Z).normalize_or_zero();
        let up = t.transform_vector3(DVec3::Y).normalize_or_zero();
        if forward == DVec3::ZERO || up == DVec3::ZERO {
            return Err(format!("{}: the sensor's `to_world` is singular", s.at));
        }
        if DMat3::from_mat4(t).determinant() < 0.0 {
            self.note(&s.at, "the sensor's `to_world` mirrors the view; lightsplit's image is not mirrored");
        }
        self.origin = position;
        let aspect = width as f64 / height as f64;
        let fov = match (p.float("fov", f64::NAN)?, p.string("focal_length")?) {
            (f, _) if !f.is_nan() => f,
            (_, focal) => {
                let mm = focal.unwrap_or("50mm");
                let f: f64 =
                    mm.trim_end_matches("mm").trim().parse().map_err(|_| {
                        format!("{}: `focal_length` `{mm}` is not a length in millimetres", s.at)
                    })?;
                // Mitsuba's: the diagonal of a 36 x 24 mm frame.
                let d = (36.0f64 * 36.0 + 24.0 * 24.0).sqrt();
                p.skip("fov_axis");
                let diag = 2.0 * (d / (2.0 * f)).atan();
                return self.camera_of(
                    s,
                    &p,
                    position,
                    forward,
                    up,
                    vertical_fov(diag.to_degrees(), "diagonal", aspect),
                    film,
                    spp,
                    seed,
                );
            }
        };
        if !(fov > 0.0 && fov < 180.0) {
            return Err(format!("{}: `fov` must lie between 0 and 180 degrees, not {fov}", s.at));
        }
        let axis = p.string("fov_axis")?.unwrap_or("x");
        if !matches!(axis, "x" | "y" | "diagonal" | "smaller" | "larger") {
            return Err(format!("{}: `fov_axis` `{axis}` is not x, y, diagonal, smaller or larger", s.at));
        }
        let vfov = vertical_fov(fov, axis, aspect);
        self.camera_of(s, &p, position, forward, up, vfov, film, spp, seed)
    }

    #[allow(clippy::too_many_arguments)]
    fn camera_of(
        &mut self,
        s: &'o Object,
        p: &Props,
        position: DVec3,
        forward: DVec3,
        up: DVec3,
        vfov: f64,
        film: FilmSettings,
        spp: u32,
        seed: u64,
    ) -> Result<(Camera, FilmSettings, u64, u32), String> {
        let lens = match s.kind.as_str() {
            "thinlens" => {
                let radius = p.float("aperture_radius", 1.0)?;
                let focus = p.float("focus_distance", 1.0)?;
                Some(Lens { radius: radius as f32, focus_distance: focus as f32 })
            }
            _ => None,
        };
        // A pinhole has no focus; Mitsuba 2's scenes give one anyway.
        for skip in ["near_clip", "far_clip", "focus_distance"] {
            p.skip(skip);
        }
        let (px, py) = (p.float("principal_point_offset_x", 0.0)?, p.float("principal_point_offset_y", 0.0)?);
        if px != 0.0 || py != 0.0 {
            self.note(&s.at, "a principal point offset is not read: the view is centred");
        }
        self.unread(p);
        let _ = position;
        let camera = Camera {
            position: Vec3::ZERO,
            look_at: forward.as_vec3(),
            up: up.as_vec3(),
            fov: vfov as f32,
            orthographic: None,
            lens,
        };
        Ok((camera, FilmSettings { spp, ..film }, seed, spp))
    }

    /// The film: its size, its reconstruction filter (Mitsuba's default a Gaussian), and its
    /// crop window; the samples per pixel are the sampler's.
    fn film(&mut self, f: &'o Object) -> Result<FilmSettings, String> {
        let p = Props::new(f);
        if f.kind != "hdrfilm" {
            self.note(&f.at, format!("<film type=\"{}\"> is read as an hdrfilm", f.kind));
        }
        let w = p.integer("width", DEFAULT_FILM.0 as i64)?;
        let h = p.integer("height", DEFAULT_FILM.1 as i64)?;
        let size = |v: i64, name: &str| {
            u32::try_from(v).ok().filter(|&v| (1..=crate::scene::limits::MAX_SIZE).contains(&v)).ok_or_else(
                || {
                    format!(
                        "{}: `{name}` must lie between 1 and {}, not {v}",
                        f.at,
                        crate::scene::limits::MAX_SIZE
                    )
                },
            )
        };
        let (w, h) = (size(w, "width")?, size(h, "height")?);
        let mut film = FilmSettings::new(w, h, 1);
        if ["crop_offset_x", "crop_offset_y", "crop_width", "crop_height"].iter().any(|k| p.has(k)) {
            let (x, y) = (p.integer("crop_offset_x", 0)?, p.integer("crop_offset_y", 0)?);
            let (cw, ch) = (p.integer("crop_width", w as i64)?, p.integer("crop_height", h as i64)?);
            if x < 0 || y < 0 || cw < 1 || ch < 1 || x + cw > w as i64 || y + ch > h as i64 {
                return Err(format!(
                    "{}: the crop window {cw} x {ch} at ({x}, {y}) does not lie within the {w} x {h} film",
                    f.at
                ));
            }
            film.width = cw as u32;
            film.height = ch as u32;
            film.window = Some(Window { film_width: w, film_height: h, x: x as u32, y: y as u32 });
        }
        for k in [
            "file_format",
            "pixel_format",
            "component_format",
            "banner",
            "high_quality_edges",
            "sample_border",
            "compensate",
            "rfilter",
        ] {
            p.skip(k);
        }
        let filters = self.children_tagged(f, "rfilter")?;
        film.pixel_filter = match filters.first() {
            None => PixelFilter::Gaussian { stddev: 0.5 },
            Some(r) => {
                let rp = Props::new(r);
                let positive = |v: f64, name: &str| match v > 0.0 && v <= 16.0 {
                    true => Ok(v as f32),
                    false => Err(format!("{}: the filter's `{name}` must lie in (0, 16], not {v}", r.at)),
                };
                let filter = match r.kind.as_str() {
                    "box" => PixelFilter::Box { radius: positive(rp.float("radius", 0.5)?, "radius")? },
                    "tent" => PixelFilter::Tent { radius: positive(rp.float("radius", 1.0)?, "radius")? },
                    "gaussian" => {
                        PixelFilter::Gaussian { stddev: positive(rp.float("stddev", 0.5)?, "stddev")? }
                    }
                    other => {
                        self.note(&r.at, format!("the `{other}` reconstruction filter is not read: a Gaussian (stddev 0.5) stands in"));
                        for k in ["b", "c", "lobes", "radius", "stddev"] {
                            rp.skip(k);
                        }
                        PixelFilter::Gaussian { stddev: 0.5 }
                    }
                };
                self.unread(&rp);
                filter
            }
        };
        self.unread(&p);
        Ok(film)
    }

    /// lightsplit's path length: Mitsuba's `max_depth` counts the camera ray's segment too.
    fn integrator(&mut self) -> Result<u32, String> {
        let Some(i) = self.children_tagged(self.root, "integrator")?.into_iter().next() else {
            return Ok(UNLIMITED_DEPTH);
        };
        // A wrapper (`aov`, `moment`) holds the integrator that renders.
        let mut i = i;
        while matches!(i.kind.as_str(), "aov" | "moment") {
            match self.children_tagged(i, "integrator")?.into_iter().next() {
                Some(inner) => i = inner,
                None => break,
            }
        }
        let p = Props::new(i);
        let depth = match i.kind.as_str() {
            "path" | "volpath" | "volpathmis" => {
                p.skip("rr_depth");
                p.skip("hide_emitters");
                let d = p.integer("max_depth", -1)?;
                match d {
                    -1 => UNLIMITED_DEPTH,
                    d if d >= 2 => (d - 1).min(UNLIMITED_DEPTH as i64) as u32,
                    d => {
                        return Err(format!(
                        "{}: `max_depth` {d}: lightsplit renders paths of at least one bounce (max_depth 2)",
                        i.at
                    ))
                    }
                }
            }
            "direct" => {
                for k in ["shading_samples", "emitter_samples", "bsdf_samples", "hide_emitters"] {
                    p.skip(k);
                }
                1
            }
            other => {
                self.note(&i.at, format!("<integrator type=\"{other}\"> is not read: lightsplit's path tracer, paths of any length"));
                return Ok(UNLIMITED_DEPTH);
            }
        };
        if p.boolean("hide_emitters", false).unwrap_or(false) {
            self.note(&i.at, "`hide_emitters` is not read: emitters are seen");
        }
        self.unread(&p);
        Ok(depth)
    }

    /// A point of the scene file's world in the scene's coordinates (relative to the origin).
    fn place(&self, p: DVec3) -> Vec3 {
        (p - self.origin).as_vec3()
    }

    fn emitter(&mut self, e: &'o Object) -> Result<(), String> {
        let p = Props::new(e);
        let color = |p: &Props, name: &str, default: f64| -> Result<Vec3, String> {
            Ok(p.color(name)?.unwrap_or(DVec3::splat(default)).as_vec3())
        };
        let light = match e.kind.as_str() {
            "point" => {
                let intensity = color(&p, "intensity", 1.0)?;
                let t = p.transform("to_world")?;
                let position = p.point("position")?.unwrap_or_else(|| t.transform_point3(DVec3::ZERO));
                Light::Point { position: self.place(position), intensity }
            }
            "constant" => Light::Sky { radiance: color(&p, "radiance", 1.0)?, diffuse_source: true },
            "directional" => {
                let irradiance = color(&p, "irradiance", 1.0)?;
                let t = p.transform("to_world")?;
                let d = p.point("direction")?.unwrap_or_else(|| t.transform_vector3(DVec3::Z));
                // lightsplit's sun points toward the light; a tiny disc stands for the direction.
                Light::sun(-d.as_vec3(), irradiance, 1e-3, false)
            }
            "spot" => {
                let intensity = color(&p, "intensity", 1.0)?;
                let t = p.transform("to_world")?;
                let cutoff = p.float("cutoff_angle", 20.0)?;
                let beam = p.float("beam_width", 0.75 * cutoff)?;
                self.note(&e.at, "a spot light's falloff is lightsplit's smoothstep in the cosine, not Mitsuba's linear ramp in the angle");
                Light::Spot {
                    position: self.place(t.transform_point3(DVec3::ZERO)),
                    direction: t.transform_vector3(DVec3::Z).normalize_or_zero().as_vec3(),
                    intensity,
                    cos_total: cutoff.to_radians().cos() as f32,
                    cos_falloff_start: beam.min(cutoff).to_radians().cos() as f32,
                }
            }
            "envmap" => {
                let path = self.file(&p, "filename")?;
                let scale = p.float("scale", 1.0)?;
                let t = p.transform("to_world")?;
                let m = DMat3::from_mat4(t);
                // Mitsuba's map: u = 0 faces -z, turning toward +x; lightsplit's is a quarter turn
                // on. A turn about +y by beta is read as lightsplit's `rotate` of beta - 90.
                let beta = m.z_axis.x.atan2(m.x_axis.x).to_degrees();
                let about_y = (m * DVec3::Y - DVec3::Y).length() < 1e-6
                    && (m.transpose() * m - DMat3::IDENTITY).to_cols_array().iter().all(|v| v.abs() < 1e-6);
                if !about_y {
                    self.note(
                        &e.at,
                        "the envmap's `to_world` is not a turn about +y: read as its turn about +y alone",
                    );
                }
                p.skip("filter_type");
                let map = EnvironmentMap::load(&path, scale as f32, (beta - 90.0) as f32)?;
                Light::Environment { map: Arc::new(map), diffuse_source: false }
            }
            "area" => return Err(format!("{}: an area emitter belongs inside a <shape>", e.at)),
            other => {
                self.note(&e.at, format!("<emitter type=\"{other}\"> is not read: left out"));
                return Ok(());
            }
        };
        self.unread(&p);
        self.lights.push(light);
        Ok(())
    }

    /// A BSDF as a material, read once however many shapes use it.
    fn material(&mut self, b: &'o Object) -> Result<u32, String> {
        if let Some(&m) = self.material_of.get(&(b as *const Object)) {
            return Ok(m);
        }
        let mut maps = Maps::default();
        let material = self.bsdf(b, false, &mut maps)?;
        let m = self.materials.len() as u32;
        self.materials.push(material);
        self.maps.push(maps);
        self.material_of.insert(b as *const Object, m);
        if let Some(id) = &b.id {
            self.material_names.push((m, id.clone()));
        }
        Ok(m)
    }

    /// Mitsuba's default material: diffuse 0.5 (black on an emitter).
    fn default_material(&mut self, emitter: bool) -> u32 {
        if let Some(&m) = self.defaults.get(&emitter) {
            return m;
        }
        let albedo = if emitter { Vec3::ZERO } else { Vec3::splat(DEFAULT_REFLECTANCE as f32) };
        let m = self.materials.len() as u32;
        self.materials.push(Material::Front(Box::new(Material::Diffuse { albedo })));
        self.maps.push(Maps::default());
        self.defaults.insert(emitter, m);
        m
    }

    /// The nested BSDF of a wrapper (`twosided`, `mask`, `bumpmap`, ...): its first.
    fn inner(&self, b: &'o Object) -> Result<Vec<&'o Object>, String> {
        let inner = self.children_tagged(b, "bsdf")?;
        if inner.is_empty() {
            return Err(format!("{}: <bsdf type=\"{}\"> holds no BSDF", b.at, b.kind));
        }
        Ok(inner)
    }

    fn bsdf(&mut self, b: &'o Object, two_sided: bool, maps: &mut Maps) -> Result<Material, String> {
        let p = Props::new(b);
        let one_sided = |m: Material| if two_sided { m } else { Material::Front(Box::new(m)) };
        let material = match b.kind.as_str() {
            "twosided" => {
                let inner = self.inner(b)?;
                if inner.len() > 1 {
                    self.note(
                        &b.at,
                        "a twosided BSDF's second (back) BSDF is not read: both sides scatter as the first",
                    );
                }
                return self.bsdf(inner[0], true, maps);
            }
            "mask" => {
                let (factor, texture) = self.scalar_texture(b, &p, "opacity", 0.5)?;
                maps.alpha = Some(Alpha { mode: AlphaMode::Blend, factor, texture });
                let inner = self.inner(b)?;
                self.unread(&p);
                return self.bsdf(inner[0], two_sided, maps);
            }
            "bumpmap" => {
                let scale = p.float("scale", 1.0)? as f32;
                let texture = self.children_tagged(b, "texture")?.into_iter().next();
                match texture {
                    Some(t) => {
                        let t = self.texture(t, Decode::Data)?;
                        maps.height = Some((t, scale));
                    }
                    None => self.note(&b.at, "a bumpmap without a texture: not bumped"),
                }
                let inner = self.inner(b)?;
                self.unread(&p);
                return self.bsdf(inner[0], two_sided, maps);
            }
            "normalmap" => {
                match self.named(b, "normalmap")? {
                    Some(t) => {
                        let t = self.texture(t, Decode::Data)?;
                        maps.normal = Some((t, 1.0));
                    }
                    None => self.note(&b.at, "a normalmap without its `normalmap` texture: not bent"),
                }
                let inner = self.inner(b)?;
                self.unread(&p);
                return self.bsdf(inner[0], two_sided, maps);
            }
            "blendbsdf" => {
                let weight = match self.named(b, "weight")? {
                    Some(t) if t.tag == "texture" => {
                        // One weight a material: the texture's mean.
                        let t = self.texture(t, Decode::Luminance { raw: false })?;
                        let mean = match self.textures.get(t as usize) {
                            Some(Texture::Image { image, .. }) => image.mean().x,
                            Some(Texture::Constant(c)) => c.x,
                            _ => 0.5,
                        };
                        self.note(
                            &b.at,
                            format!("a blendbsdf's weight texture is read as its mean, {mean:.3}"),
                        );
                        mean
                    }
                    Some(o) => return Err(format!("{}: `weight` is a <{}>, not a texture", o.at, o.tag)),
                    None => p.float("weight", 0.5)? as f32,
                };
                if !(0.0..=1.0).contains(&weight) {
                    return Err(format!("{}: a blendbsdf's `weight` must lie in [0, 1], not {weight}", b.at));
                }
                let inner = self.inner(b)?;
                if inner.len() != 2 {
                    return Err(format!("{}: a blendbsdf blends two BSDFs, not {}", b.at, inner.len()));
                }
                // Each BSDF its own textures; where both have some, the first's are read.
                let before = *maps;
                let (mut ma, mut mb) = (before, before);
                let first = self.bsdf(inner[0], two_sided, &mut ma)?;
                let second = self.bsdf(inner[1], two_sided, &mut mb)?;
                *maps = match (ma != before, mb != before) {
                    (true, true) => {
                        self.note(
                            &b.at,
                            "both of a blendbsdf's BSDFs read textures: the first's are read for both",
                        );
                        ma
                    }
                    (false, true) => mb,
                    _ => ma,
                };
                self.unread(&p);
                return Ok(Material::Blend(Box::new(BlendMaterial { a: first, b: second, weight })));
            }
            "diffuse" => {
                let (albedo, texture) = self.color_texture(b, &p, "reflectance", DEFAULT_REFLECTANCE)?;
                maps.color = texture;
                one_sided(Material::Diffuse { albedo })
            }
            "conductor" | "roughconductor" => {
                let (eta, k) = self.complex_ior(b, &p)?;
                let (specular, texture) = self.color_texture(b, &p, "specular_reflectance", 1.0)?;
                if texture.is_some() {
                    self.note(&b.at, "a textured `specular_reflectance` is read as 1");
                }
                let specular = if texture.is_some() { Vec3::ONE } else { specular };
                let facets = match b.kind.as_str() {
                    "roughconductor" => Some(self.microfacet(b, &p, true)?),
                    _ => None,
                };
                one_sided(Material::Conductor(Box::new(ConductorMaterial { eta, k, specular, facets })))
            }
            "dielectric" | "thindielectric" | "roughdielectric" => {
                let int = ior(&p, "int_ior", "bk7")?;
                let ext = ior(&p, "ext_ior", "air")?;
                if int <= 0.0 || ext <= 0.0 || int == ext {
                    return Err(format!(
                        "{}: the interior and exterior indices of refraction must be positive and differ",
                        b.at
                    ));
                }
                let reflectance = self.plain_color(b, &p, "specular_reflectance", 1.0)?;
                let transmittance = self.plain_color(b, &p, "specular_transmittance", 1.0)?;
                let facets = match b.kind.as_str() {
                    "roughdielectric" => Some(self.microfacet(b, &p, true)?),
                    _ => None,
                };
                Material::Dielectric(Box::new(DielectricMaterial {
                    eta: (int / ext) as f32,
                    reflectance,
                    transmittance,
                    thin: b.kind == "thindielectric",
                    facets,
                }))
            }
            "plastic" | "roughplastic" => {
                let int = ior(&p, "int_ior", "polypropylene")?;
                let ext = ior(&p, "ext_ior", "air")?;
                if int <= 0.0 || ext <= 0.0 || int == ext {
                    return Err(format!(
                        "{}: the interior and exterior indices of refraction must be positive and differ",
                        b.at
                    ));
                }
                let eta = (int / ext) as f32;
                let (diffuse, texture) = self.color_texture(b, &p, "diffuse_reflectance", 0.5)?;
                maps.color = texture;
                let specular = self.plain_color(b, &p, "specular_reflectance", 1.0)?;
                let nonlinear = p.boolean("nonlinear", false)?;
                let d_mean = match texture.and_then(|t| self.textures.get(t as usize)) {
                    Some(Texture::Image { image, .. }) => image.mean().element_sum() / 3.0,
                    _ => diffuse.element_sum() / 3.0,
                };
                let facets = match b.kind.as_str() {
                    "roughplastic" => Some(self.microfacet(b, &p, false)?),
                    _ => None,
                };
                one_sided(Material::Plastic(Box::new(PlasticMaterial::new(
                    eta, diffuse, d_mean, specular, nonlinear, facets,
                ))))
            }
            other => {
                self.note(&b.at, format!("<bsdf type=\"{other}\"> is not read: diffuse, reflectance 0.5"));
                return Ok(Material::Diffuse { albedo: Vec3::splat(DEFAULT_REFLECTANCE as f32) });
            }
        };
        self.unread(&p);
        Ok(material)
    }

    /// A rough BSDF's distribution (`anisotropic` whether it may be).
    fn microfacet(&mut self, b: &'o Object, p: &Props, anisotropic: bool) -> Result<Microfacet, String> {
        let kind = match p.string("distribution")?.unwrap_or("beckmann") {
            "beckmann" => Distribution::Beckmann,
            "ggx" => Distribution::Ggx,
            other => return Err(format!("{}: `distribution` `{other}` is not beckmann or ggx", b.at)),
        };
        p.skip("sample_visible");
        let alpha = |name: &str, default: f64| -> Result<f64, String> {
            if self.named(b, name)?.is_some() {
                return Err(format!("{}: a textured `{name}` is not read; give a number", b.at));
            }
            p.float(name, default)
        };
        let (au, av) = if p.has("alpha_u") || p.has("alpha_v") {
            if !anisotropic {
                return Err(format!("{}: a {} is isotropic: give `alpha`", b.at, b.kind));
            }
            (alpha("alpha_u", 0.1)?, alpha("alpha_v", 0.1)?)
        } else {
            let a = alpha("alpha", 0.1)?;
            (a, a)
        };
        if !(au >= 0.0 && av >= 0.0) {
            return Err(format!("{}: the roughness `alpha` must be at least 0", b.at));
        }
        Ok(Microfacet::new(kind, au as f32, av as f32))
    }

    /// A conductor's complex index: a named material's (as Mitsuba tabulates it, reduced to
    /// RGB by its `scalar_rgb` variant), or `eta` and `k`.
    fn complex_ior(&mut self, b: &'o Object, p: &Props) -> Result<(Vec3, Vec3), String> {
        let material = p.string("material")?;
        if p.has("eta") || p.has("k") {
            if material.is_some() {
                return Err(format!(
                    "{}: give a conductor's `material` or its `eta` and `k`, not both",
                    b.at
                ));
            }
            let eta = self.plain_color(b, p, "eta", 0.0)?;
            let k = self.plain_color(b, p, "k", 1.0)?;
            return Ok((eta, k));
        }
        let name = material.unwrap_or("none");
        named_conductor(name).ok_or_else(|| format!("{}: `{name}` is not one of Mitsuba's conductors", b.at))
    }

    /// A colour that must be a value (no texture).
    fn plain_color(&mut self, b: &'o Object, p: &Props, name: &str, default: f64) -> Result<Vec3, String> {
        let (c, texture) = self.color_texture(b, p, name, default)?;
        if texture.is_some() {
            self.note(&b.at, format!("a textured `{name}` is not read: {default}"));
            return Ok(Vec3::splat(default as f32));
        }
        Ok(c)
    }

    /// A colour parameter: its value, or a texture (then the value is 1).
    fn color_texture(
        &mut self,
        b: &'o Object,
        p: &Props,
        name: &str,
        default: f64,
    ) -> Result<(Vec3, Option<u32>), String> {
        if let Some(c) = p.color(name)? {
            return Ok((c.as_vec3(), None));
        }
        match self.named(b, name)? {
            Some(t) if t.tag == "texture" => {
                let t = self.texture(t, Decode::Color)?;
                Ok((Vec3::ONE, Some(t)))
            }
            Some(o) => Err(format!("{}: `{name}` is a <{}>, not a texture", o.at, o.tag)),
            None => Ok((Vec3::splat(default as f32), None)),
        }
    }

    /// A scalar parameter: a value, or a texture (as data) and the factor 1.
    fn scalar_texture(
        &mut self,
        b: &'o Object,
        p: &Props,
        name: &str,
        default: f64,
    ) -> Result<(f32, Option<u32>), String> {
        if p.has(name) {
            return Ok((p.float(name, default)? as f32, None));
        }
        match self.named(b, name)? {
            Some(t) if t.tag == "texture" => {
                Ok((1.0, Some(self.texture(t, Decode::Luminance { raw: false })?)))
            }
            Some(o) => Err(format!("{}: `{name}` is a <{}>, not a texture", o.at, o.tag)),
            None => Ok((default as f32, None)),
        }
    }

    fn image(&mut self, path: PathBuf, decode: Decode) -> Result<Arc<Image>, String> {
        if let Some(i) = self.images.get(&(path.clone(), decode)) {
            return Ok(i.clone());
        }
        let image = match decode {
            Decode::Color | Decode::Luminance { raw: false } => crate::scene::image::read(&path)?,
            Decode::Data | Decode::Luminance { raw: true } => crate::scene::image::read_linear(&path)?,
        };
        let mut image = image;
        if let Decode::Luminance { .. } = decode {
            for p in &mut image.pixels {
                *p = Vec3::splat(MITSUBA_LUMINANCE.dot(*p));
            }
        }
        let image = Arc::new(image);
        self.images.insert((path, decode), image.clone());
        Ok(image)
    }

    fn texture(&mut self, t: &'o Object, decode: Decode) -> Result<u32, String> {
        let p = Props::new(t);
        let to_uv = uv_transform(p.transform("to_uv")?);
        let texture = match t.kind.as_str() {
            "bitmap" => {
                let path = self.file(&p, "filename")?;
                let raw = p.boolean("raw", false)?;
                let decode = match decode {
                    Decode::Luminance { .. } => Decode::Luminance { raw },
                    _ if raw => Decode::Data,
                    other => other,
                };
                let nearest = match p.string("filter_type")?.unwrap_or("bilinear") {
                    "bilinear" => false,
                    "nearest" => true,
                    other => {
                        return Err(format!("{}: `filter_type` `{other}` is not bilinear or nearest", t.at))
                    }
                };
                let wrap = match p.string("wrap_mode")?.unwrap_or("repeat") {
                    "repeat" => Wrap::Repeat,
                    "mirror" => Wrap::Mirror,
                    "clamp" => Wrap::Clamp,
                    other => {
                        return Err(format!("{}: `wrap_mode` `{other}` is not repeat, mirror or clamp", t.at))
                    }
                };
                let image = self.image(path, decode)?;
                Texture::image(image, Vec2::ONE, to_uv, Sampling { wrap: [wrap; 2], nearest, set: 0 })
            }
            "checkerboard" => {
                let c0 = p.color("color0")?.unwrap_or(DVec3::splat(0.4)).as_vec3();
                let c1 = p.color("color1")?.unwrap_or(DVec3::splat(0.2)).as_vec3();
                // Mitsuba's cell (u < 1/2, v < 1/2) is color0; its v runs down the image.
                let mut image = Image::new(2, 2);
                image.set(0, 0, c0);
                image.set(1, 0, c1);
                image.set(0, 1, c1);
                image.set(1, 1, c0);
                let sampling = Sampling { wrap: [Wrap::Repeat; 2], nearest: true, set: 0 };
                Texture::image(Arc::new(image), Vec2::ONE, to_uv, sampling)
            }
            other => {
                self.note(&t.at, format!("<texture type=\"{other}\"> is not read: grey 0.5"));
                Texture::Constant(Vec3::splat(0.5))
            }
        };
        self.unread(&p);
        self.textures.push(texture);
        Ok(self.textures.len() as u32 - 1)
    }

    /// A shape, placed in the world, or (`group` given) into a shape group's own coordinates.
    fn shape(&mut self, s: &'o Object, group: Option<&mut Group>) -> Result<(), String> {
        let p = Props::new(s);
        if s.kind == "instance" {
            return self.instance(s, &p);
        }
        let name = s.id.clone().unwrap_or_else(|| format!("{} {}", s.kind, self.shapes.len()));
        let emitters = self.children_tagged(s, "emitter")?;
        let mut emission = Vec3::ZERO;
        for e in &emitters {
            let ep = Props::new(e);
            if e.kind != "area" {
                return Err(format!("{}: a <shape> holds only area emitters, not `{}`", e.at, e.kind));
            }
            if self.named(e, "radiance")?.is_some() {
                self.note(&e.at, "a textured `radiance` is not read: 1");
                emission = Vec3::ONE;
            } else {
                emission = ep.color("radiance")?.unwrap_or(DVec3::ONE).as_vec3();
            }
            self.unread(&ep);
        }
        let bsdfs = self.children_tagged(s, "bsdf")?;
        let material = match bsdfs.first() {
            Some(b) => self.material(b)?,
            None => self.default_material(!emitters.is_empty()),
        };
        let t = p.transform("to_world")?;
        let flip = p.boolean("flip_normals", false)?;
        let face_normals = p.boolean("face_normals", false)?;
        let raw = match s.kind.as_str() {
            "sphere" => {
                let center = p.point("center")?.unwrap_or(DVec3::ZERO);
                let radius = p.float("radius", 1.0)?;
                let m = DMat3::from_mat4(t);
                let scales = [m.x_axis.length(), m.y_axis.length(), m.z_axis.length()];
                let uniform = (scales[0] - scales[1]).abs() < 1e-6 * scales[0]
                    && (scales[0] - scales[2]).abs() < 1e-6 * scales[0];
                if !uniform {
                    self.note(
                        &s.at,
                        "a sphere stretched by its `to_world` is read as a sphere of its mean scale",
                    );
                }
                if flip && emission != Vec3::ZERO {
                    self.note(&s.at, "`flip_normals` on an emitting sphere is not read: it shines outward");
                }
                let center = t.transform_point3(center);
                let radius = radius.abs() * (scales.iter().sum::<f64>() / 3.0);
                self.unread(&p);
                let geometry = match group {
                    Some(_) => Geometry::Sphere { center: center.as_vec3(), radius: radius as f32 },
                    None => Geometry::Sphere { center: self.place(center), radius: radius as f32 },
                };
                return self.push(geometry, material, emission, name, group);
            }
            "obj" | "ply" => {
                let path = self.file(&p, "filename")?;
                let parts = if s.kind == "obj" {
                    crate::scene::obj::load(&path)?.parts
                } else {
                    crate::scene::ply::load(&path)?
                };
                let mut m = RawMesh::default();
                let has_normals = parts.iter().all(|q| q.normals.is_some());
                let has_uvs = parts.iter().all(|q| q.uvs.is_some());
                let mut normals = Vec::new();
                let mut uvs = Vec::new();
                for q in parts {
                    let base = m.positions.len() as u32;
                    m.positions.extend(q.positions.iter().copied());
                    m.indices.extend(q.indices.iter().map(|t| t.map(|i| i + base)));
                    if let Some(ns) = q.normals {
                        normals.extend(ns.iter().map(|n| n.as_dvec3()));
                    }
                    if let Some(us) = q.uvs {
                        uvs.extend(us.iter().map(|u| u.as_dvec2()));
                    }
                }
                m.normals = has_normals.then_some(normals);
                m.uvs = has_uvs.then_some(uvs);
                if s.kind == "obj" && !p.boolean("flip_tex_coords", true)? {
                    if let Some(us) = &mut m.uvs {
                        us.iter_mut().for_each(|u| u.y = 1.0 - u.y);
                    }
                }
                if s.kind == "ply" && p.boolean("flip_tex_coords", false)? {
                    if let Some(us) = &mut m.uvs {
                        us.iter_mut().for_each(|u| u.y = 1.0 - u.y);
                    }
                }
                m
            }
            "serialized" => {
                let path = self.file(&p, "filename")?;
                let index = p.integer("shape_index", 0)?;
                let index = usize::try_from(index)
                    .map_err(|_| format!("{}: `shape_index` {index} is negative", s.at))?;
                shapes::serialized(&path, index)?
            }
            "rectangle" => shapes::rectangle(),
            "cube" => shapes::cube(),
            "disk" => shapes::disk(),
            "cylinder" => {
                let p0 = p.point("p0")?.unwrap_or(DVec3::ZERO);
                let p1 = p.point("p1")?.unwrap_or(DVec3::Z);
                let r = p.float("radius", 1.0)?;
                let axis = p1 - p0;
                let len = axis.length();
                if !(len > 0.0 && r > 0.0) {
                    return Err(format!("{}: a cylinder needs p0 and p1 apart and a radius above 0", s.at));
                }
                let dir = axis / len;
                let (x, y) = dir.any_orthonormal_pair();
                let frame = DMat4::from_cols(
                    (x * r).extend(0.0),
                    (y * r).extend(0.0),
                    axis.extend(0.0),
                    p0.extend(1.0),
                );
                let mut m = shapes::cylinder();
                for q in &mut m.positions {
                    *q = frame.transform_point3(*q);
                }
                if let Some(ns) = &mut m.normals {
                    let nm = DMat3::from_mat4(frame).inverse().transpose();
                    ns.iter_mut().for_each(|n| *n = (nm * *n).normalize_or_zero());
                }
                m
            }
            other => {
                self.note(&s.at, format!("<shape type=\"{other}\"> is not read: left out"));
                return Ok(());
            }
        };
        let mut raw = raw;
        if face_normals {
            raw.normals = None;
        } else if raw.normals.is_none() {
            raw.smooth_normals();
        }
        if flip {
            raw.flip();
        }
        self.unread(&p);
        let offset = if group.is_some() { DVec3::ZERO } else { self.origin };
        let mesh = placed(&raw, &t, offset);
        self.push(Geometry::Triangles(mesh), material, emission, name, group)
    }

    fn push(
        &mut self,
        geometry: Geometry,
        material: u32,
        emission: Vec3,
        name: String,
        group: Option<&mut Group>,
    ) -> Result<(), String> {
        match group {
            Some(g) => g.parts.push((geometry, material, emission, name)),
            None => {
                self.objects.push(name.clone());
                let object = self.objects.len() as u32 - 1;
                self.shapes.push(Shape { name, geometry, material, emission, object });
            }
        }
        Ok(())
    }

    /// An `instance` of a shape group: the group's meshes shared, placed by the instance's
    /// `to_world` (copied where it mirrors, or where they emit).
    fn instance(&mut self, s: &'o Object, p: &Props) -> Result<(), String> {
        let group = self.children_tagged(s, "shape")?.into_iter().find(|o| o.kind == "shapegroup");
        let Some(group) = group else {
            return Err(format!("{}: an instance refers to no shapegroup", s.at));
        };
        let g = match self.groups.get(&(group as *const Object)) {
            Some(g) => g.clone(),
            None => {
                let mut g = Group { parts: Vec::new() };
                for c in &group.children {
                    let o = self.resolve(c)?;
                    if o.tag == "shape" {
                        self.shape(o, Some(&mut g))?;
                    }
                }
                let g = Arc::new(g);
                self.groups.insert(group as *const Object, g.clone());
                g
            }
        };
        let t = p.transform("to_world")?;
        self.unread(p);
        let base = s.id.clone().unwrap_or_else(|| format!("instance {}", self.shapes.len()));
        let world = DAffine3::from_mat4(t);
        let relative = DAffine3 { translation: world.translation - self.origin, ..world };
        let affine =
            glam::Affine3A::from_mat3_translation(relative.matrix3.as_mat3(), relative.translation.as_vec3());
        for (geometry, material, emission, name) in &g.parts {
            let name = format!("{base}/{name}");
            let geometry = match geometry {
                Geometry::Sphere { center, radius } => {
                    let scale = (DMat3::from_mat4(t).determinant().abs()).cbrt();
                    Geometry::Sphere {
                        center: self.place(t.transform_point3(center.as_dvec3())),
                        radius: (*radius as f64 * scale) as f32,
                    }
                }
                Geometry::Triangles(mesh) => {
                    match Instance::new(affine).filter(|_| *emission == Vec3::ZERO) {
                        Some(instance) => {
                            Geometry::Triangles(Mesh { instance: Some(Box::new(instance)), ..mesh.clone() })
                        }
                        None => Geometry::Triangles(transformed(mesh, &t, self.origin)),
                    }
                }
            };
            self.push(geometry, *material, *emission, name, None)?;
        }
        Ok(())
    }
}

/// The vertical field of view of Mitsuba's `fov` along `axis` on a film of `aspect` (width
/// over height).
fn vertical_fov(fov: f64, axis: &str, aspect: f64) -> f64 {
    let t = (0.5 * fov).to_radians().tan();
    let vertical = match axis {
        "y" => t,
        "diagonal" => t / (1.0 + aspect * aspect).sqrt(),
        "smaller" if aspect < 1.0 => t / aspect,
        "smaller" => t,
        "larger" if aspect > 1.0 => t / aspect,
        "larger" => t,
        _ => t / aspect,
    };
    2.0 * vertical.atan().to_degrees()
}

/// Mitsuba's `to_uv` (on its uv, v down) as a map of lightsplit's uv (v up): F T F, F the flip
/// of v.
fn uv_transform(m: DMat4) -> Option<Affine2> {
    if m == DMat4::IDENTITY {
        return None;
    }
    let t = Affine2::from_cols_array(&[
        m.x_axis.x as f32,
        m.x_axis.y as f32,
        m.y_axis.x as f32,
        m.y_axis.y as f32,
        m.w_axis.x as f32,
        m.w_axis.y as f32,
    ]);
    let flip = Affine2::from_cols_array(&[1.0, 0.0, 0.0, -1.0, 0.0, 1.0]);
    Some(flip * t * flip)
}

/// A raw mesh placed by `t`, less `origin`, in f32: normals by the inverse transpose, the
/// winding turned where `t` mirrors (so the geometric normal stays on the side of the normals).
fn placed(raw: &RawMesh, t: &DMat4, origin: DVec3) -> Mesh {
    let m3 = DMat3::from_mat4(*t);
    let nm = m3.inverse().transpose();
    let positions: Arc<[Vec3A]> =
        raw.positions.iter().map(|&q| (t.transform_point3(q) - origin).as_vec3a()).collect();
    let mut indices = raw.indices.clone();
    if m3.determinant() < 0.0 {
        indices.iter_mut().for_each(|t| t.swap(1, 2));
    }
    let normals = raw
        .normals
        .as_ref()
        .map(|ns| ns.iter().map(|&n| (nm * n).normalize_or_zero().as_vec3()).collect::<Arc<[Vec3]>>());
    let uvs = raw.uvs.as_ref().map(|us| us.iter().map(|u| u.as_vec2()).collect::<Arc<[Vec2]>>());
    Mesh::new(positions, indices.into(), normals, uvs)
}

/// A group's mesh (in its own coordinates) copied into the scene by `t`, less `origin`.
fn transformed(mesh: &Mesh, t: &DMat4, origin: DVec3) -> Mesh {
    let raw = RawMesh {
        positions: mesh.positions.iter().map(|p| glam::Vec3::from(*p).as_dvec3()).collect(),
        normals: mesh.normals.as_ref().map(|ns| ns.iter().map(|n| n.as_dvec3()).collect()),
        uvs: mesh.uvs.as_ref().map(|us| us.iter().map(|u| u.as_dvec2()).collect()),
        indices: mesh.indices.to_vec(),
    };
    placed(&raw, t, origin)
}

/// Every object with an id, by its id; an id given twice is an error.
fn collect_ids<'o>(o: &'o Object, ids: &mut HashMap<&'o str, &'o Object>) -> Result<(), String> {
    if let Some(id) = &o.id {
        if let Some(first) = ids.insert(id.as_str(), o) {
            return Err(format!("{}: the id `{id}` is given twice (first at {})", o.at, first.at));
        }
    }
    for c in &o.children {
        if let Child::Object(c) = c {
            collect_ids(c, ids)?;
        }
    }
    Ok(())
}

/// An index of refraction: a number, or the name of one of Mitsuba's materials.
fn ior(p: &Props, name: &str, default: &str) -> Result<f64, String> {
    if let Ok(Some(named)) = p.string(name) {
        return IORS.iter().find(|(n, _)| *n == named).map(|(_, v)| *v).ok_or_else(|| {
            format!("{}: `{named}` is not one of Mitsuba's named indices of refraction", p.at())
        });
    }
    if p.has(name) {
        return p.float(name, 1.0);
    }
    IORS.iter().find(|(n, _)| *n == default).map(|(_, v)| *v).ok_or_else(|| format!("no index `{default}`"))
}

/// Mitsuba's named indices of refraction (`include/mitsuba/render/ior.h`).
const IORS: &[(&str, f64)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbondioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbontetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("siliconeoil", 1.52045),
    ("bromine", 1.661),
    ("waterice", 1.31),
    ("fusedquartz", 1.458),
    ("pyrex", 1.470),
    ("acrylicglass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodiumchloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

/// Mitsuba 3's conductors: the complex index (eta, k) its `scalar_rgb` variant makes of each
/// tabulated spectrum (`scripts/mitsuba/conductors.py` prints them from Mitsuba 3.9.1).
/// The index of refraction `eta + i k` of one of Mitsuba's named conductors (`Au`, `Cu`, ...,
/// and `none`), reduced to RGB as its `scalar_rgb` variant does.
pub fn named_conductor(name: &str) -> Option<(Vec3, Vec3)> {
    // `none`: a perfect mirror (Fresnel 1 at every angle), Mitsuba's default.
    if name == "none" {
        return Some((Vec3::ZERO, Vec3::ONE));
    }
    CONDUCTORS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|(_, eta, k)| (Vec3::from_array(*eta), Vec3::from_array(*k)))
}

const CONDUCTORS: &[(&str, [f32; 3], [f32; 3])] = &[
    ("a-C", [2.94405, 2.22714, 1.96816], [0.887465, 0.799299, 0.81529]),
    ("Ag", [0.155276, 0.116728, 0.138388], [4.82835, 3.12222, 2.1469]),
    ("Al", [1.6575, 0.880405, 0.521244], [9.22381, 6.2695, 4.837]),
    ("AlAs", [3.6053, 3.23294, 2.21632], [0.000679437, 0.0, 0.00751271]),
    ("AlAs_palik", [3.6053, 3.23294, 2.21632], [0.000679437, 0.0, 0.00751271]),
    ("AlSb", [0.0, 4.13937, 4.66925], [0.0, 0.0940091, 1.30057]),
    ("Au", [0.143036, 0.375307, 1.44205], [3.983, 2.38556, 1.60336]),
    ("Be", [4.18501, 3.18503, 2.78406], [3.83547, 3.01012, 2.86899]),
    ("Cr", [4.36967, 2.91651, 1.6549], [5.20655, 4.23131, 3.7547]),
    ("CsI", [2.1449, 1.70232, 1.66243], [0.0, 0.0, 0.0]),
    ("Cu", [0.201005, 0.92375, 1.10222], [3.91326, 2.45305, 2.14209]),
    ("Cu2O", [3.55177, 2.94987, 2.75188], [0.114207, 0.193897, 0.606134]),
    ("CuO", [3.24754, 2.44781, 2.21022], [0.52109, 0.570031, 0.722179]),
    ("d-C", [2.70872, 2.31883, 2.2289], [0.0, 0.0, 0.0]),
    ("Hg", [2.39894, 1.44003, 0.90957], [6.32759, 4.37192, 3.42176]),
    ("HgTe", [4.77904, 3.2312, 2.6599], [1.63161, 1.58081, 1.72929]),
    ("Ir", [3.0863, 2.08219, 1.61791], [5.59215, 4.06709, 3.26731]),
    ("K", [0.0640432, 0.0464098, 0.0381849], [2.1042, 1.34894, 0.913126]),
    ("Li", [0.265791, 0.195618, 0.220949], [3.54015, 2.31112, 1.66861]),
    ("MgO", [2.08958, 1.65072, 1.59488], [4.3327e-12, 0.0, 2.49865e-11]),
    ("Mo", [4.48397, 3.52513, 2.77631], [4.11144, 3.42083, 3.15061]),
    ("Na_palik", [0.0602694, 0.0561409, 0.0619884], [3.17927, 2.11249, 1.57904]),
    ("Nb", [3.42007, 2.79009, 2.39563], [3.44139, 2.73767, 2.57975]),
    ("Ni_palik", [2.3673, 1.66337, 1.46708], [4.49881, 3.05015, 2.34544]),
    ("Rh", [2.58579, 1.86022, 1.55426], [6.78226, 4.70299, 3.97607]),
    ("Se", [4.05831, 2.84294, 2.82085], [0.75405, 0.638444, 0.521808]),
    ("SiC", [3.17234, 2.52597, 2.47937], [7.53766e-07, 0.0, 1.01925e-05]),
    ("SnTe", [4.52425, 1.98164, 1.28159], [0.0, 0.0, 0.0]),
    ("Ta", [2.06272, 2.39294, 2.62793], [2.40836, 1.74149, 1.94703]),
    ("Te", [7.39023, 4.4821, 2.63711], [3.25602, 3.52706, 3.29205]),
    ("ThF4", [1.83071, 1.44223, 1.38765], [0.0, 0.0, 0.0]),
    ("TiC", [3.70053, 2.83742, 2.58229], [3.26564, 2.35159, 2.17279]),
    ("TiN", [1.64845, 1.15052, 1.37982], [3.36833, 1.9435, 1.10207]),
    ("TiO2", [3.45661, 2.80174, 2.90517], [0.000105265, 0.0, 0.000652887]),
    ("VC", [3.65757, 2.75274, 2.53267], [3.0683, 2.19869, 1.96319]),
    ("V_palik", [4.27758, 3.51295, 2.76107], [3.4913, 2.88945, 3.11152]),
    ("VN", [2.8656, 2.11919, 1.94009], [3.03224, 2.05612, 1.61631]),
    ("W", [4.37082, 3.30025, 2.99841], [3.50064, 2.60487, 2.27323]),
];
