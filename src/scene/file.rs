//! The TOML scene file: serde structs that reject unknown keys and non-finite numbers, then a
//! pass that resolves names, builds geometry and reports every problem as `file:line: message`.
//! The format is documented in `docs/scene-format.md`.

use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat3, Vec2, Vec3, Vec3A};
use serde::de::{self, Deserializer, Visitor};
use serde::Deserialize;
use toml::Spanned;

use super::sky::CloudySky;
use super::texture::{Pattern, Texture};
use super::{
    obj, procedural, teapot, Camera, FilmSettings, Geometry, Light, Maps, Material, Mesh, RenderSettings,
    Scene, SceneError, Shape,
};

/// A finite number: TOML's `nan` and `inf` are rejected where they are written.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F(pub f32);

impl<'de> Deserialize<'de> for F {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Finite;
        impl Visitor<'_> for Finite {
            type Value = F;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a finite number")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<F, E> {
                Ok(F(v as f32))
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<F, E> {
                Ok(F(v as f32))
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<F, E> {
                if !v.is_finite() {
                    Err(E::custom(format!("{v} is not a finite number")))
                } else if v.abs() > f32::MAX as f64 {
                    Err(E::custom(format!("{v} is too large for a 32-bit float")))
                } else {
                    Ok(F(v as f32))
                }
            }
        }
        d.deserialize_any(Finite)
    }
}

type V3 = [F; 3];

/// The finest terrain: 2 x 4096^2, about 33.5 million triangles.
const MAX_TERRAIN: u32 = 4096;
/// The finest teapot tessellation: 64 * 256^2 = 4.2 million triangles.
const MAX_TEAPOT: u32 = 256;

fn v3(v: V3) -> Vec3 {
    Vec3::new(v[0].0, v[1].0, v[2].0)
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileScene {
    camera: Spanned<FileCamera>,
    film: Option<FileFilm>,
    render: Option<FileRender>,
    #[serde(default)]
    material: Vec<Spanned<FileMaterial>>,
    #[serde(default)]
    shape: Vec<Spanned<FileShape>>,
    #[serde(default)]
    light: Vec<Spanned<FileLight>>,
    filter: Option<Spanned<FilterSection>>,
    #[serde(default)]
    texture: Vec<Spanned<FileTexture>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileTexture {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    color: Option<V3>,
    color2: Option<V3>,
    size: Option<F>,
    frequency: Option<F>,
    octaves: Option<u32>,
    seed: Option<u32>,
    file: Option<String>,
    repeat: Option<[F; 2]>,
}

/// The `[filter]` section as written: the scene checks its keys and that its numbers are
/// finite; `filter::Setting::from_section` reads it (kernels, targets and edge stops belong to
/// the filters).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FilterSection {
    /// The kernel, by name or by its weights.
    pub kernel: KernelSpec,
    /// What the filter applies to (`indirect`, `image` or `none`).
    pub target: Option<String>,
    /// Only neighbours that show the centre's object.
    pub edge_aware: Option<bool>,
    /// The normal tolerance of the edge stops, in degrees.
    #[serde(default, deserialize_with = "finite")]
    pub edge_normal: Option<f32>,
    /// The relative depth tolerance of the edge stops.
    #[serde(default, deserialize_with = "finite")]
    pub edge_depth: Option<f32>,
    /// Leave pixels that saw more than one object unfiltered.
    pub edge_pure: Option<bool>,
    /// The line of the section's header, for the errors of whoever reads it.
    #[serde(skip)]
    pub line: usize,
}

/// A kernel by name or by its weights (row by row).
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(untagged)]
pub enum KernelSpec {
    /// A named kernel (`box3`, `weighted3`, ...), or weights written as one string.
    Name(String),
    /// The weights of an odd square kernel.
    Weights(#[serde(deserialize_with = "finite_weights")] Vec<f32>),
}

fn finite<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f32>, D::Error> {
    Ok(Option::<F>::deserialize(d)?.map(|f| f.0))
}

fn finite_weights<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
    Ok(Vec::<F>::deserialize(d)?.into_iter().map(|f| f.0).collect())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileCamera {
    position: V3,
    look_at: V3,
    up: Option<V3>,
    fov: Option<Spanned<F>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileFilm {
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    spp: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRender {
    max_depth: Option<Spanned<u32>>,
    seed: Option<u64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileMaterial {
    name: String,
    #[serde(rename = "type")]
    kind: String,
    color: Option<V3>,
    ior: Option<F>,
    roughness: Option<F>,
    base: Option<V3>,
    texture: Option<String>,
    bump: Option<String>,
    bump_height: Option<F>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileTransform {
    scale: Option<F>,
    rotate: Option<V3>,
    translate: Option<V3>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileShape {
    #[serde(rename = "type")]
    kind: String,
    name: Option<String>,
    material: Option<String>,
    object: Option<String>,
    emission: Option<V3>,
    transform: Option<FileTransform>,
    // sphere
    center: Option<V3>,
    radius: Option<F>,
    // quad
    vertices: Option<Vec<V3>>,
    // box
    min: Option<V3>,
    max: Option<V3>,
    // mesh
    file: Option<String>,
    // terrain
    resolution: Option<Spanned<u32>>,
    size: Option<F>,
    height: Option<F>,
    seed: Option<u32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileLight {
    #[serde(rename = "type")]
    kind: String,
    position: Option<V3>,
    intensity: Option<V3>,
    direction: Option<V3>,
    irradiance: Option<V3>,
    angular_diameter: Option<F>,
    radiance: Option<V3>,
    diffuse_source: Option<bool>,
    // spot
    cone_angle: Option<F>,
    falloff_start: Option<F>,
    // cloudy sky
    zenith: Option<V3>,
    clear: Option<V3>,
    cloud_cover: Option<F>,
    cloud_scale: Option<F>,
    seed: Option<u32>,
}

/// 1-based line of a byte offset.
fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].bytes().filter(|&b| b == b'\n').count() + 1
}

/// Reports errors against one scene file.
struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Ctx<'_> {
    fn err<T>(&self, span: std::ops::Range<usize>, message: impl Into<String>) -> Result<T, SceneError> {
        Err(SceneError::new(self.path, Some(line_of(self.text, span.start)), message))
    }

    /// Rejects keys that the table's `type` does not use: present keys minus allowed ones.
    fn only(
        &self,
        span: std::ops::Range<usize>,
        what: &str,
        present: &[(&'static str, bool)],
        allowed: &[&str],
    ) -> Result<(), SceneError> {
        let extra: Vec<&str> =
            present.iter().filter(|(key, is)| *is && !allowed.contains(key)).map(|(key, _)| *key).collect();
        if extra.is_empty() {
            Ok(())
        } else {
            self.err(span, format!("{what} does not take `{}`", extra.join("`, `")))
        }
    }

    fn need<T: Copy>(
        &self,
        span: std::ops::Range<usize>,
        what: &str,
        key: &str,
        v: Option<T>,
    ) -> Result<T, SceneError> {
        match v {
            Some(v) => Ok(v),
            None => self.err(span, format!("{what} needs `{key}`")),
        }
    }
}

/// Reads and resolves a scene file. Every problem is one [`SceneError`] naming the file and line.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| SceneError::new(path, None, format!("cannot read the scene file: {e}")))?;
    parse(path, &text)
}

/// Parses scene text as if read from `path` (relative mesh paths resolve against its directory).
pub fn parse(path: &Path, text: &str) -> Result<Scene, SceneError> {
    let file: FileScene = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| line_of(text, s.start));
        let message: Vec<&str> = e.message().lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        SceneError::new(path, line, message.join("; "))
    })?;
    let ctx = Ctx { path, text };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();

    let camera = camera(&ctx, &file.camera)?;
    let film = film(&ctx, file.film.as_ref())?;
    let render = RenderSettings {
        max_depth: match file.render.as_ref().and_then(|r| r.max_depth.as_ref()) {
            Some(d) if *d.get_ref() == 0 => return ctx.err(d.span(), "`max_depth` must be at least 1"),
            Some(d) => *d.get_ref(),
            None => 8,
        },
        seed: file.render.as_ref().and_then(|r| r.seed).unwrap_or(0),
    };

    let mut textures = Vec::new();
    let mut texture_ids: HashMap<String, u32> = HashMap::new();
    for t in &file.texture {
        let span = t.span();
        if texture_ids.contains_key(&t.get_ref().name) {
            return ctx.err(span, format!("texture `{}` is defined twice", t.get_ref().name));
        }
        texture_ids.insert(t.get_ref().name.clone(), textures.len() as u32);
        textures.push(texture(&ctx, &dir, t)?);
    }

    let mut materials = Vec::new();
    let mut maps = Vec::new();
    let mut material_ids: HashMap<String, u32> = HashMap::new();
    for m in &file.material {
        let span = m.span();
        let m = m.get_ref();
        if material_ids.contains_key(&m.name) {
            return ctx.err(span, format!("material `{}` is defined twice", m.name));
        }
        let only = |key: &str, present: bool, kinds: &str| -> Result<(), SceneError> {
            if present {
                ctx.err(span.clone(), format!("a {} material does not take `{key}` (only {kinds})", m.kind))
            } else {
                Ok(())
            }
        };
        if m.kind != "glass" {
            only("ior", m.ior.is_some(), "glass")?;
        }
        if m.kind != "glossy" {
            only("roughness", m.roughness.is_some(), "glossy")?;
            only("base", m.base.is_some(), "glossy")?;
        }
        let material = match m.kind.as_str() {
            "diffuse" => {
                let color = v3(m.color.unwrap_or([F(0.8); 3]));
                if color.min_element() < 0.0 || color.max_element() > 1.0 {
                    return ctx.err(span, "a diffuse `color` must lie in [0, 1]");
                }
                Material::Diffuse { albedo: color }
            }
            "mirror" | "glass" => {
                let color = v3(m.color.unwrap_or([F(1.0); 3]));
                if color.min_element() < 0.0 || color.max_element() > 1.0 {
                    return ctx.err(span, "a `color` must lie in [0, 1]");
                }
                if m.kind == "mirror" {
                    Material::Mirror { color }
                } else {
                    let ior = m.ior.map_or(1.5, |i| i.0);
                    if ior <= 0.0 {
                        return ctx.err(span, "`ior` must be positive");
                    }
                    Material::Glass { ior, color }
                }
            }
            "glossy" => {
                let specular = v3(m.color.unwrap_or([F(0.9); 3]));
                let base = v3(m.base.unwrap_or([F(0.0); 3]));
                if specular.min_element() < 0.0 || specular.max_element() > 1.0 {
                    return ctx.err(span, "a glossy `color` must lie in [0, 1]");
                }
                if base.min_element() < 0.0 || base.max_element() > 1.0 {
                    return ctx.err(span, "a glossy `base` must lie in [0, 1]");
                }
                let roughness = m.roughness.map_or(0.3, |r| r.0);
                if !(0.0..=1.0).contains(&roughness) {
                    return ctx.err(span, "`roughness` must lie in [0, 1]");
                }
                Material::Glossy { specular, roughness, base }
            }
            other => {
                return ctx.err(
                    span,
                    format!("unknown material type `{other}` (expected diffuse, mirror, glass or glossy)"),
                )
            }
        };
        let texture_id = |name: &String| match texture_ids.get(name) {
            Some(&t) => Ok(t),
            None => ctx.err(span.clone(), format!("unknown texture `{name}`")),
        };
        let color = match &m.texture {
            Some(_) if !matches!(material, Material::Diffuse { .. } | Material::Glossy { .. }) => {
                return ctx
                    .err(span, "only diffuse and glossy materials take a `texture` (the albedo or the base)")
            }
            Some(name) => Some(texture_id(name)?),
            None => None,
        };
        let bump = match &m.bump {
            Some(name) => {
                let t = texture_id(name)?;
                if !textures[t as usize].is_solid() {
                    return ctx.err(
                        span,
                        format!("`bump` needs a solid texture (checker or noise); `{name}` is not"),
                    );
                }
                Some((t, m.bump_height.map_or(0.02, |h| h.0)))
            }
            None if m.bump_height.is_some() => return ctx.err(span, "`bump_height` needs a `bump` texture"),
            None => None,
        };
        material_ids.insert(m.name.clone(), materials.len() as u32);
        materials.push(material);
        maps.push(Maps { color, bump });
    }

    let mut builder = ShapeBuilder { shapes: Vec::new(), objects: Vec::new(), object_ids: HashMap::new() };
    for s in &file.shape {
        add_shape(&ctx, &dir, s, &mut materials, &material_ids, &mut builder)?;
    }

    let mut lights = Vec::new();
    for l in &file.light {
        lights.push(light(&ctx, l)?);
    }

    let filter = file.filter.map(|f| {
        let line = line_of(text, f.span().start);
        FilterSection { line, ..f.into_inner() }
    });

    Ok(Scene {
        filter,
        textures,
        maps,
        path: path.to_path_buf(),
        camera,
        film,
        render,
        materials,
        shapes: builder.shapes,
        lights,
        objects: builder.objects,
    })
}

fn camera(ctx: &Ctx, c: &Spanned<FileCamera>) -> Result<Camera, SceneError> {
    let span = c.span();
    let c = c.get_ref();
    let position = v3(c.position);
    let look_at = v3(c.look_at);
    let up = c.up.map(v3).unwrap_or(Vec3::Y);
    let fov = match &c.fov {
        Some(f) if !(f.get_ref().0 > 0.0 && f.get_ref().0 < 180.0) => {
            return ctx.err(f.span(), "`fov` must lie strictly between 0 and 180 degrees")
        }
        Some(f) => f.get_ref().0,
        None => 40.0,
    };
    let forward = look_at - position;
    if forward.length_squared() == 0.0 {
        return ctx.err(span, "the camera's `position` and `look_at` are the same point");
    }
    if forward.cross(up).length_squared() <= 1e-12 * forward.length_squared() * up.length_squared() {
        return ctx.err(span, "the camera's `up` is zero or parallel to its view direction");
    }
    Ok(Camera { position, look_at, up, fov })
}

fn film(ctx: &Ctx, f: Option<&FileFilm>) -> Result<FilmSettings, SceneError> {
    let get = |v: Option<&Spanned<u32>>, name: &str, default: u32, max: u32| -> Result<u32, SceneError> {
        match v {
            Some(v) if *v.get_ref() == 0 || *v.get_ref() > max => {
                ctx.err(v.span(), format!("`{name}` must lie between 1 and {max}"))
            }
            Some(v) => Ok(*v.get_ref()),
            None => Ok(default),
        }
    };
    Ok(FilmSettings {
        width: get(f.and_then(|f| f.width.as_ref()), "width", 256, 1 << 16)?,
        height: get(f.and_then(|f| f.height.as_ref()), "height", 256, 1 << 16)?,
        spp: get(f.and_then(|f| f.spp.as_ref()), "spp", 16, 1 << 24)?,
    })
}

struct ShapeBuilder {
    shapes: Vec<Shape>,
    objects: Vec<String>,
    object_ids: HashMap<String, u32>,
}

impl ShapeBuilder {
    fn object(&mut self, name: &str) -> u32 {
        if let Some(&id) = self.object_ids.get(name) {
            return id;
        }
        let id = self.objects.len() as u32;
        self.objects.push(name.to_string());
        self.object_ids.insert(name.to_string(), id);
        id
    }
}

/// An affine transform from the scene file: scale, then rotate about x, y, z (degrees), then
/// translate.
struct Transform {
    linear: Mat3,
    translate: Vec3,
    scale: f32,
    rotates: bool,
}

impl Transform {
    fn new(t: Option<&FileTransform>) -> Self {
        let scale = t.and_then(|t| t.scale).map_or(1.0, |s| s.0);
        let r = t.and_then(|t| t.rotate).map(v3).unwrap_or(Vec3::ZERO);
        let rotation = Mat3::from_rotation_z(r.z.to_radians())
            * Mat3::from_rotation_y(r.y.to_radians())
            * Mat3::from_rotation_x(r.x.to_radians());
        Transform {
            linear: rotation * Mat3::from_diagonal(Vec3::splat(scale)),
            translate: t.and_then(|t| t.translate).map(v3).unwrap_or(Vec3::ZERO),
            scale,
            rotates: r != Vec3::ZERO,
        }
    }

    fn point(&self, p: Vec3) -> Vec3 {
        self.linear * p + self.translate
    }

    /// Normals under the transform (by the inverse transpose of the linear part).
    fn normals(&self, normals: &[Vec3]) -> Arc<[Vec3]> {
        let inv_t = self.linear.inverse().transpose();
        normals.iter().map(|&v| (inv_t * v).normalize_or_zero()).collect()
    }
}

fn add_shape(
    ctx: &Ctx,
    dir: &Path,
    s: &Spanned<FileShape>,
    materials: &mut Vec<Material>,
    material_ids: &HashMap<String, u32>,
    out: &mut ShapeBuilder,
) -> Result<(), SceneError> {
    let span = s.span();
    let s = s.get_ref();
    let present = [
        ("center", s.center.is_some()),
        ("radius", s.radius.is_some()),
        ("vertices", s.vertices.is_some()),
        ("min", s.min.is_some()),
        ("max", s.max.is_some()),
        ("file", s.file.is_some()),
        ("resolution", s.resolution.is_some()),
        ("size", s.size.is_some()),
        ("height", s.height.is_some()),
        ("seed", s.seed.is_some()),
    ];
    let what = format!("a {} shape", s.kind);
    let index = out.shapes.len();
    let name = s.name.clone().unwrap_or_else(|| format!("{}{}", s.kind, index));
    let emission = s.emission.map(v3).unwrap_or(Vec3::ZERO);
    if emission.min_element() < 0.0 {
        return ctx.err(span.clone(), "`emission` must not be negative");
    }
    let transform = Transform::new(s.transform.as_ref());
    if transform.scale <= 0.0 {
        return ctx.err(span, "a transform's `scale` must be positive");
    }

    let material = match &s.material {
        Some(m) => match material_ids.get(m) {
            Some(&id) => Some(id),
            None => return ctx.err(span, format!("unknown material `{m}`")),
        },
        None => None,
    };
    let default_material = |materials: &mut Vec<Material>| -> u32 {
        materials.push(Material::Diffuse { albedo: Vec3::splat(0.8) });
        (materials.len() - 1) as u32
    };

    let geometry = match s.kind.as_str() {
        "sphere" => {
            ctx.only(span.clone(), &what, &present, &["center", "radius"])?;
            if transform.rotates {
                return ctx.err(span, "a sphere takes no `rotate`");
            }
            let radius = ctx.need(span.clone(), &what, "radius", s.radius)?.0 * transform.scale;
            if radius < 0.0 {
                return ctx.err(span, "a sphere's `radius` must not be negative");
            }
            let center = transform.point(s.center.map(v3).unwrap_or(Vec3::ZERO));
            Geometry::Sphere { center, radius }
        }
        "quad" => {
            ctx.only(span.clone(), &what, &present, &["vertices"])?;
            let v = ctx.need(span.clone(), &what, "vertices", s.vertices.as_ref())?;
            if v.len() != 4 {
                return ctx.err(span, format!("a quad needs 4 `vertices`, not {}", v.len()));
            }
            let p: Vec<Vec3> = v.iter().map(|&p| transform.point(v3(p))).collect();
            let mut quad = mesh(&p, &[[0, 1, 2], [0, 2, 3]]);
            // An image's bottom left, bottom right, top right and top left.
            quad.uvs = Some([Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y].into());
            Geometry::Triangles(quad)
        }
        "box" => {
            ctx.only(span.clone(), &what, &present, &["min", "max"])?;
            let lo = v3(ctx.need(span.clone(), &what, "min", s.min)?);
            let hi = v3(ctx.need(span.clone(), &what, "max", s.max)?);
            if lo.cmpge(hi).any() {
                return ctx.err(span, "a box's `min` must be below its `max` on every axis");
            }
            let (p, i) = box_mesh(lo, hi);
            let p: Vec<Vec3> = p.iter().map(|&q| transform.point(q)).collect();
            Geometry::Triangles(mesh(&p, &i))
        }
        "mesh" => {
            ctx.only(span.clone(), &what, &present, &["file"])?;
            let file = ctx.need(span.clone(), &what, "file", s.file.as_ref())?;
            let obj_path: PathBuf = dir.join(file);
            let line = Some(line_of(ctx.text, span.start));
            let parts = obj::load(&obj_path)
                .map_err(|e| SceneError::new(ctx.path, line, format!("mesh `{file}`: {e}")))?;
            if parts.is_empty() {
                return ctx.err(span, format!("mesh `{file}` has no faces"));
            }
            // Each OBJ object is a shape of its own (and an object of its own, unless the scene
            // file names one), with its .mtl material unless the scene file gives one.
            for part in parts {
                let part_material = match material {
                    Some(id) => id,
                    None => match part.material {
                        Some(m) => {
                            materials.push(Material::Diffuse { albedo: m.diffuse });
                            (materials.len() - 1) as u32
                        }
                        None => default_material(materials),
                    },
                };
                let part_emission = if s.emission.is_some() {
                    emission
                } else {
                    part.material.map_or(Vec3::ZERO, |m| m.emission)
                };
                let positions: Vec<Vec3> = part.positions.iter().map(|&p| transform.point(p)).collect();
                let normals = part.normals.map(|n| transform.normals(&n));
                let object_name = s.object.clone().unwrap_or_else(|| format!("{name}/{}", part.name));
                let object = out.object(&object_name);
                out.shapes.push(Shape {
                    name: format!("{name}/{}", part.name),
                    geometry: Geometry::Triangles(Mesh {
                        positions: positions.iter().map(|&p| Vec3A::from(p)).collect(),
                        indices: part.indices.into(),
                        normals,
                        uvs: part.uvs.map(Into::into),
                    }),
                    material: part_material,
                    emission: part_emission,
                    object,
                });
            }
            return Ok(());
        }
        "terrain" => {
            ctx.only(span.clone(), &what, &present, &["resolution", "size", "height", "seed"])?;
            let resolution = match &s.resolution {
                Some(r) if !(1..=MAX_TERRAIN).contains(r.get_ref()) => {
                    return ctx.err(r.span(), format!("`resolution` must lie between 1 and {MAX_TERRAIN}"))
                }
                Some(r) => *r.get_ref(),
                None => 64,
            };
            let size = s.size.map_or(10.0, |v| v.0);
            if size <= 0.0 {
                return ctx.err(span, "a terrain's `size` must be positive");
            }
            let height = s.height.map_or(1.0, |v| v.0);
            let mut mesh = procedural::terrain(resolution, size, height, s.seed.unwrap_or(0));
            if transform.rotates || transform.scale != 1.0 || transform.translate != Vec3::ZERO {
                mesh.positions =
                    mesh.positions.iter().map(|&p| Vec3A::from(transform.point(p.into()))).collect();
            }
            Geometry::Triangles(mesh)
        }
        "teapot" => {
            ctx.only(span.clone(), &what, &present, &["resolution"])?;
            let resolution = match &s.resolution {
                Some(r) if !(1..=MAX_TEAPOT).contains(r.get_ref()) => {
                    return ctx.err(
                        r.span(),
                        format!("a teapot's `resolution` must lie between 1 and {MAX_TEAPOT}"),
                    )
                }
                Some(r) => *r.get_ref(),
                None => 8,
            };
            let mut mesh = teapot::teapot(resolution);
            mesh.positions = mesh.positions.iter().map(|&p| Vec3A::from(transform.point(p.into()))).collect();
            mesh.normals = mesh.normals.map(|n| transform.normals(&n));
            Geometry::Triangles(mesh)
        }
        other => {
            return ctx.err(
                span,
                format!("unknown shape type `{other}` (expected sphere, quad, box, mesh, terrain or teapot)"),
            )
        }
    };
    let material = material.unwrap_or_else(|| default_material(materials));
    let object = out.object(s.object.as_deref().unwrap_or(&name));
    out.shapes.push(Shape { name, geometry, material, emission, object });
    Ok(())
}

fn mesh(p: &[Vec3], indices: &[[u32; 3]]) -> Mesh {
    Mesh {
        positions: p.iter().map(|&q| Vec3A::from(q)).collect(),
        indices: indices.into(),
        normals: None,
        uvs: None,
    }
}

/// An axis-aligned box as 12 triangles wound counter-clockwise seen from outside.
fn texture(ctx: &Ctx, dir: &Path, t: &Spanned<FileTexture>) -> Result<Texture, SceneError> {
    let span = t.span();
    let t = t.get_ref();
    let present = [
        ("color", t.color.is_some()),
        ("color2", t.color2.is_some()),
        ("size", t.size.is_some()),
        ("frequency", t.frequency.is_some()),
        ("octaves", t.octaves.is_some()),
        ("seed", t.seed.is_some()),
        ("file", t.file.is_some()),
        ("repeat", t.repeat.is_some()),
    ];
    let what = format!("a {} texture", t.kind);
    let a = v3(t.color.unwrap_or([F(0.0); 3]));
    let b = v3(t.color2.unwrap_or([F(1.0); 3]));
    if a.min_element() < 0.0 || b.min_element() < 0.0 {
        return ctx.err(span, "texture colours must not be negative");
    }
    let pattern = match t.kind.as_str() {
        "constant" => {
            ctx.only(span.clone(), &what, &present, &["color"])?;
            return Ok(Texture::Constant(v3(ctx.need(span, &what, "color", t.color)?)));
        }
        "checker" => {
            ctx.only(span.clone(), &what, &present, &["color", "color2", "size"])?;
            let size = t.size.map_or(1.0, |s| s.0);
            if size <= 0.0 {
                return ctx.err(span, "a checker's `size` must be positive");
            }
            return Ok(Texture::Checker { a, b, size });
        }
        "image" => {
            ctx.only(span.clone(), &what, &present, &["file", "repeat"])?;
            let file = ctx.need(span.clone(), &what, "file", t.file.as_ref())?;
            let image = super::image::read(&dir.join(file))
                .or_else(|e| ctx.err(span.clone(), format!("texture `{}`: {e}", t.name)))?;
            let repeat = t.repeat.map_or(Vec2::ONE, |[u, v]| Vec2::new(u.0, v.0));
            if repeat.min_element() <= 0.0 {
                return ctx.err(span, "`repeat` must be positive");
            }
            return Ok(Texture::Image { image: Arc::new(image), repeat });
        }
        "perlin" => Pattern::Perlin,
        "fbm" => Pattern::Fbm,
        "turbulence" => Pattern::Turbulence,
        "marble" => Pattern::Marble,
        other => {
            return ctx.err(
                span,
                format!("unknown texture type `{other}` (constant, checker, image, perlin, fbm, turbulence or marble)"),
            )
        }
    };
    ctx.only(span.clone(), &what, &present, &["color", "color2", "frequency", "octaves", "seed"])?;
    let frequency = t.frequency.map_or(1.0, |f| f.0);
    if frequency <= 0.0 {
        return ctx.err(span, "`frequency` must be positive");
    }
    let octaves = t.octaves.unwrap_or(6);
    if !(1..=16).contains(&octaves) {
        return ctx.err(span, "`octaves` must lie between 1 and 16");
    }
    Ok(Texture::Noise { pattern, a, b, frequency, octaves, seed: t.seed.unwrap_or(0) })
}

fn box_mesh(lo: Vec3, hi: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let p: Vec<Vec3> = (0..8)
        .map(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        })
        .collect();
    // Faces as corner quads (counter-clockwise from outside): -x, +x, -y, +y, -z, +z.
    let quads = [[0, 4, 6, 2], [1, 3, 7, 5], [0, 1, 5, 4], [2, 6, 7, 3], [0, 2, 3, 1], [4, 5, 7, 6]];
    let mut tris = Vec::with_capacity(12);
    for [a, b, c, d] in quads {
        tris.push([a, b, c]);
        tris.push([a, c, d]);
    }
    (p, tris)
}

fn light(ctx: &Ctx, l: &Spanned<FileLight>) -> Result<Light, SceneError> {
    let span = l.span();
    let l = l.get_ref();
    let present = [
        ("position", l.position.is_some()),
        ("intensity", l.intensity.is_some()),
        ("direction", l.direction.is_some()),
        ("irradiance", l.irradiance.is_some()),
        ("angular_diameter", l.angular_diameter.is_some()),
        ("radiance", l.radiance.is_some()),
        ("diffuse_source", l.diffuse_source.is_some()),
        ("cone_angle", l.cone_angle.is_some()),
        ("falloff_start", l.falloff_start.is_some()),
        ("zenith", l.zenith.is_some()),
        ("clear", l.clear.is_some()),
        ("cloud_cover", l.cloud_cover.is_some()),
        ("cloud_scale", l.cloud_scale.is_some()),
        ("seed", l.seed.is_some()),
    ];
    let what = format!("a {} light", l.kind);
    let non_negative = |v: Vec3, key: &str| -> Result<Vec3, SceneError> {
        if v.min_element() < 0.0 {
            ctx.err(span.clone(), format!("`{key}` must not be negative"))
        } else {
            Ok(v)
        }
    };
    match l.kind.as_str() {
        "point" => {
            ctx.only(span.clone(), &what, &present, &["position", "intensity"])?;
            Ok(Light::Point {
                position: v3(ctx.need(span.clone(), &what, "position", l.position)?),
                intensity: non_negative(
                    v3(ctx.need(span.clone(), &what, "intensity", l.intensity)?),
                    "intensity",
                )?,
            })
        }
        "sun" => {
            ctx.only(
                span.clone(),
                &what,
                &present,
                &["direction", "irradiance", "angular_diameter", "diffuse_source"],
            )?;
            let direction = v3(ctx.need(span.clone(), &what, "direction", l.direction)?);
            if direction.length_squared() == 0.0 {
                return ctx.err(span, "a sun's `direction` must not be zero");
            }
            let irradiance =
                non_negative(v3(ctx.need(span.clone(), &what, "irradiance", l.irradiance)?), "irradiance")?;
            let diameter = l.angular_diameter.map_or(0.53, |d| d.0);
            if !(diameter > 0.0 && diameter < 180.0) {
                return ctx
                    .err(span, "a sun's `angular_diameter` must lie strictly between 0 and 180 degrees");
            }
            // 1 - cos(half angle) = 2 sin^2(half angle / 2), in f64: about 1e-5 for the real sun,
            // which f32 cannot hold as a difference from 1.
            let half = (diameter as f64 / 2.0).to_radians();
            let one_minus_cos = 2.0 * (half / 2.0).sin().powi(2);
            let solid_angle = 2.0 * std::f64::consts::PI * one_minus_cos;
            Ok(Light::Sun {
                direction: direction.normalize(),
                radiance: irradiance / solid_angle as f32,
                one_minus_cos: one_minus_cos as f32,
                diffuse_source: l.diffuse_source.unwrap_or(false),
            })
        }
        "sky" if l.zenith.is_some() => {
            ctx.only(
                span.clone(),
                "a cloudy sky (one with `zenith`)",
                &present,
                &["zenith", "clear", "cloud_cover", "cloud_scale", "seed", "diffuse_source"],
            )?;
            let zenith = non_negative(v3(ctx.need(span.clone(), &what, "zenith", l.zenith)?), "zenith")?;
            let clear = non_negative(l.clear.map_or(zenith, v3), "clear")?;
            let cover = l.cloud_cover.map_or(0.5, |c| c.0);
            if !(0.0..=1.0).contains(&cover) {
                return ctx.err(span, "`cloud_cover` must lie in [0, 1]");
            }
            let scale = l.cloud_scale.map_or(0.5, |c| c.0);
            if scale <= 0.0 {
                return ctx.err(span, "`cloud_scale` must be positive");
            }
            Ok(Light::CloudySky {
                sky: CloudySky { zenith, clear, cover, scale, seed: l.seed.unwrap_or(0) },
                diffuse_source: l.diffuse_source.unwrap_or(true),
            })
        }
        "sky" => {
            ctx.only(span.clone(), &what, &present, &["radiance", "diffuse_source"])?;
            Ok(Light::Sky {
                radiance: non_negative(
                    v3(ctx.need(span.clone(), &what, "radiance", l.radiance)?),
                    "radiance",
                )?,
                diffuse_source: l.diffuse_source.unwrap_or(true),
            })
        }
        "spot" => {
            ctx.only(
                span.clone(),
                &what,
                &present,
                &["position", "direction", "intensity", "cone_angle", "falloff_start"],
            )?;
            let direction = v3(ctx.need(span.clone(), &what, "direction", l.direction)?);
            if direction.length_squared() == 0.0 {
                return ctx.err(span, "a spot light's `direction` must not be zero");
            }
            let cone = l.cone_angle.map_or(30.0, |a| a.0);
            if !(cone > 0.0 && cone <= 180.0) {
                return ctx.err(span, "a spot light's `cone_angle` must lie in (0, 180] degrees");
            }
            let start = l.falloff_start.map_or(0.75 * cone, |a| a.0);
            if !(0.0..=cone).contains(&start) {
                return ctx.err(span, "`falloff_start` must lie between 0 and `cone_angle` degrees");
            }
            Ok(Light::Spot {
                position: v3(ctx.need(span.clone(), &what, "position", l.position)?),
                direction: direction.normalize(),
                intensity: non_negative(
                    v3(ctx.need(span.clone(), &what, "intensity", l.intensity)?),
                    "intensity",
                )?,
                cos_total: cone.to_radians().cos(),
                cos_falloff_start: start.to_radians().cos(),
            })
        }
        other => ctx.err(
            span,
            format!(
                "unknown light type `{other}` (expected point, spot, sun or sky; an emissive shape has `emission`)"
            ),
        ),
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A camera and nothing else: the smallest scene that parses.
    pub(crate) const MINIMAL: &str = "[camera]\nposition = [0, 1, -5]\nlook_at = [0, 1, 0]\n";

    pub(crate) fn parse_str(text: &str) -> Result<Scene, SceneError> {
        parse(Path::new("test.toml"), text)
    }

    pub(crate) fn error_line(text: &str) -> (Option<usize>, String) {
        let e = parse_str(text).expect_err("must fail");
        (e.line, e.message)
    }

    #[test]
    fn minimal_scene_has_defaults() {
        let s = parse_str(MINIMAL).expect("parses");
        assert_eq!((s.film.width, s.film.height, s.film.spp), (256, 256, 16));
        assert_eq!(s.render.max_depth, 8);
        assert_eq!(s.camera.fov, 40.0);
    }

    #[test]
    fn unknown_key_names_its_line() {
        let (line, msg) = error_line(&format!("{MINIMAL}[film]\nwidth = 64\nhieght = 64\n"));
        assert_eq!(line, Some(6), "{msg}");
        assert!(msg.contains("hieght"), "{msg}");
    }

    #[test]
    fn nan_and_inf_are_rejected_where_written() {
        let text = format!("{MINIMAL}[[shape]]\ntype = \"sphere\"\nradius = nan\n");
        let (line, msg) = error_line(&text);
        assert_eq!(line, Some(6), "{msg}");
        assert!(msg.contains("finite"), "{msg}");
        let (line, msg) = error_line("[camera]\nposition = [0, inf, -5]\nlook_at = [0, 1, 0]\n");
        assert_eq!(line, Some(2), "{msg}");
    }

    #[test]
    fn keys_of_another_type_are_rejected() {
        let text = format!("{MINIMAL}[[shape]]\ntype = \"sphere\"\nradius = 1\nvertices = []\n");
        let (line, msg) = error_line(&text);
        assert_eq!(line, Some(4), "{msg}");
        assert!(msg.contains("vertices"), "{msg}");
    }

    #[test]
    fn material_keys_belong_to_their_types() {
        let glossy = "[[material]]\nname = \"g\"\ntype = \"glossy\"\n";
        let s =
            parse_str(&format!("{MINIMAL}{glossy}roughness = 0.5\nbase = [0.5, 0, 0]\n")).expect("parses");
        let Material::Glossy { roughness, base, specular } = s.materials[0] else {
            panic!("{:?}", s.materials)
        };
        // Its GGX alpha, 0.25, is the renderer's business: `render::bsdf::alpha`, tested there.
        assert_eq!((roughness, base, specular), (0.5, Vec3::new(0.5, 0.0, 0.0), Vec3::splat(0.9)));
        for (extra, needle) in
            [("roughness = 1.5\n", "roughness"), ("ior = 1.5\n", "ior"), ("base = [2, 0, 0]\n", "base")]
        {
            let (line, msg) = error_line(&format!("{MINIMAL}{glossy}{extra}"));
            assert_eq!(line, Some(4), "{msg}");
            assert!(msg.contains(needle), "{msg}");
        }
        let (_, msg) = error_line(&format!(
            "{MINIMAL}[[material]]\nname = \"d\"\ntype = \"diffuse\"\nbase = [1, 1, 1]\n"
        ));
        assert!(msg.contains("base") && msg.contains("only glossy"), "{msg}");
    }

    #[test]
    fn textures_and_their_errors() {
        let marble = "[[texture]]\nname = \"m\"\ntype = \"marble\"\nfrequency = 2\n";
        let mat = "[[material]]\nname = \"x\"\ntype = \"diffuse\"\n";
        let s = parse_str(&format!("{MINIMAL}{marble}{mat}texture = \"m\"\nbump = \"m\"\n")).expect("parses");
        assert!(matches!(s.textures[0], Texture::Noise { pattern: Pattern::Marble, frequency: 2.0, .. }));
        assert_eq!(s.maps(0), Maps { color: Some(0), bump: Some((0, 0.02)) });
        assert_eq!(s.maps(7), Maps::default());
        let image = "[[texture]]\nname = \"i\"\ntype = \"image\"\nfile = \"nowhere.png\"\n";
        for (text, needle, line) in [
            (format!("{MINIMAL}{mat}texture = \"nope\"\n"), "nope", 4),
            (format!("{MINIMAL}{image}"), "nowhere.png", 4),
            (format!("{MINIMAL}{marble}octaves = 40\n"), "octaves", 4),
            (format!("{MINIMAL}{marble}file = \"a.png\"\n"), "file", 4),
            (
                format!("{MINIMAL}{marble}[[material]]\nname = \"g\"\ntype = \"mirror\"\ntexture = \"m\"\n"),
                "only diffuse",
                8,
            ),
            (format!("{MINIMAL}{mat}bump_height = 1\n"), "bump", 4),
        ] {
            let (l, msg) = error_line(&text);
            assert_eq!(l, Some(line), "{msg}");
            assert!(msg.contains(needle), "{needle}: {msg}");
        }
        // An image texture cannot be a bump map (it has no gradient in space).
        let dir = tempfile::tempdir().expect("tempdir");
        ::image::RgbImage::new(2, 2).save(dir.path().join("i.png")).expect("png");
        let text = format!("{MINIMAL}{}{mat}bump = \"i\"\n", image.replace("nowhere.png", "i.png"));
        let e = parse(&dir.path().join("s.toml"), &text).expect_err("must fail");
        assert!(e.message.contains("solid"), "{}", e.message);
    }

    #[test]
    fn unknown_material_and_missing_mesh_are_errors() {
        let text = format!("{MINIMAL}\n[[shape]]\ntype = \"sphere\"\nradius = 1\nmaterial = \"nope\"\n");
        let (line, msg) = error_line(&text);
        assert_eq!(line, Some(5));
        assert!(msg.contains("nope"));
        let text = format!("{MINIMAL}[[shape]]\ntype = \"mesh\"\nfile = \"missing.obj\"\n");
        let (line, msg) = error_line(&text);
        assert_eq!(line, Some(4));
        assert!(msg.contains("missing.obj"), "{msg}");
    }

    #[test]
    fn sun_keeps_its_tiny_solid_angle() {
        let text =
            format!("{MINIMAL}[[light]]\ntype = \"sun\"\ndirection = [0, 1, 0]\nirradiance = [1, 1, 1]\n");
        let s = parse_str(&text).expect("parses");
        let Light::Sun { one_minus_cos, radiance, .. } = &s.lights[0] else { panic!("sun") };
        let half = (0.53f64 / 2.0).to_radians();
        let expected = 1.0 - half.cos();
        assert!(((*one_minus_cos as f64) - expected).abs() < 1e-6 * expected);
        // Radiance times solid angle gives back the irradiance.
        let e = radiance.x as f64 * 2.0 * std::f64::consts::PI * (*one_minus_cos as f64);
        assert!((e - 1.0).abs() < 1e-5, "{e}");
    }

    #[test]
    fn box_triangles_face_outwards() {
        let (p, tris) = box_mesh(Vec3::splat(-1.0), Vec3::splat(1.0));
        for [a, b, c] in tris {
            let (a, b, c) = (p[a as usize], p[b as usize], p[c as usize]);
            let n = (b - a).cross(c - a);
            let centre = (a + b + c) / 3.0;
            assert!(n.dot(centre) > 0.0, "triangle {a} {b} {c} faces inwards");
        }
    }

    #[test]
    fn transform_applies_scale_rotate_translate() {
        let t = Transform::new(Some(&FileTransform {
            scale: Some(F(2.0)),
            rotate: Some([F(0.0), F(90.0), F(0.0)]),
            translate: Some([F(1.0), F(0.0), F(0.0)]),
        }));
        let p = t.point(Vec3::X);
        assert!((p - Vec3::new(1.0, 0.0, -2.0)).length() < 1e-5, "{p}");
    }
}
