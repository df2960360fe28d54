//! The scene: what a scene file describes, resolved into flat arrays the renderer reads
//! (camera, materials, shapes with their triangles or spheres, lights). Loading lives in
//! [`file`] (TOML), [`obj`] (Wavefront OBJ meshes) and [`image`] (texture images).

pub mod analysis;
pub mod cutout;
pub mod environment;
pub mod file;
pub mod gltf;
pub mod image;
pub mod limits;
pub mod mitsuba;
pub mod noise;
pub mod obj;
pub mod ply;
pub mod procedural;
pub mod sky;
pub mod teapot;
pub mod texture;

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Affine3A, DVec3, Mat3A, Vec2, Vec3, Vec3A};

pub use file::{FilterSection, KernelSpec};
pub use mitsuba::materials::{BlendMaterial, ConductorMaterial, DielectricMaterial, PlasticMaterial};

/// Loads a scene: a glTF file (`.gltf`, `.glb`) as a whole scene, any other as a scene file.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    load_with_camera(path, None)
}

/// [`load`], a glTF file rendered through the camera `camera` names (its index from 0, or its
/// name); any other file refuses the choice.
pub fn load_with_camera(path: &Path, camera: Option<&str>) -> Result<Scene, SceneError> {
    load_with(path, &LoadOptions { camera: camera.map(str::to_owned), defines: Vec::new() })
}

/// What the command line adds to a scene file: a glTF file's camera (`--camera`) and a Mitsuba
/// file's parameters (`-D name=value`). Each is refused by a file of another kind.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// A glTF file's camera: its index from 0 or its name.
    pub camera: Option<String>,
    /// A Mitsuba XML file's `$name` parameters, which take precedence over its `<default>`s.
    pub defines: Vec<(String, String)>,
}

/// [`load`] with the command line's [`LoadOptions`].
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if let (Some(choice), false) = (&options.camera, matches!(ext.as_deref(), Some("gltf" | "glb"))) {
        return Err(SceneError::new(
            path,
            None,
            format!("--camera `{choice}` picks one of a glTF file's cameras; this is not a glTF file"),
        ));
    }
    if let (Some((name, _)), false) = (options.defines.first(), ext.as_deref() == Some("xml")) {
        return Err(SceneError::new(
            path,
            None,
            format!("-D {name}=... sets a parameter of a Mitsuba XML scene; this is not an XML file"),
        ));
    }
    match ext.as_deref() {
        Some("gltf" | "glb") => gltf::scene(path, options.camera.as_deref()),
        Some("obj" | "ply") => file::mesh_scene(path),
        Some("xml") => mitsuba::scene(path, &options.defines),
        _ => file::load(path),
    }
    .and_then(|scene| scene.check_extent().map(|()| scene))
}

/// A camera framing the bounds `lo`..`hi` of a model rendered by itself (a glTF or mesh file
/// without a camera): from the front and a little above, at 40 degrees, the bounding sphere
/// filling the view. Its position and unit view direction.
pub fn framing(lo: glam::DVec3, hi: glam::DVec3) -> (glam::DVec3, glam::DVec3) {
    let centre = 0.5 * (lo + hi);
    let radius = (0.5 * (hi - lo).length()).max(1e-6);
    let distance = radius / (0.5 * FRAMING_FOV as f64).to_radians().sin();
    let back = glam::DVec3::new(0.0, 0.35, 1.0).normalize();
    (centre + back * distance, -back)
}

/// The field of view of [`framing`], in degrees.
pub const FRAMING_FOV: f32 = 40.0;

/// The note of a model lit by the default environment, as it says so.
pub fn default_environment_note(emissive: bool) -> String {
    let emission = if emissive { ", and its own emission" } else { "" };
    format!(
        "no lights: lit by the default environment, a uniform white sky of radiance 1{emission} \
         (`--environment FILE.hdr|white|none` changes it)"
    )
}

/// A bad scene file: one message naming the file and, where known, the line.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneError {
    pub file: PathBuf,
    pub line: Option<usize>,
    pub message: String,
}

impl SceneError {
    pub fn new(file: &Path, line: Option<usize>, message: impl Into<String>) -> Self {
        SceneError { file: file.to_path_buf(), line, message: message.into() }
    }
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{}: {}", self.file.display(), line, self.message),
            None => write!(f, "{}: {}", self.file.display(), self.message),
        }
    }
}

impl std::error::Error for SceneError {}

/// A pinhole or an orthographic camera.
#[derive(Clone, Copy, Debug)]
pub struct Camera {
    pub position: Vec3,
    pub look_at: Vec3,
    pub up: Vec3,
    /// Vertical field of view in degrees (a pinhole camera's).
    pub fov: f32,
    /// An orthographic camera's view height in scene units (from the image's bottom edge to its
    /// top), its rays parallel; `None` for a pinhole camera.
    pub orthographic: Option<f32>,
    /// A thin lens (depth of field); `None` for a pinhole (everything in focus).
    pub lens: Option<Lens>,
}

/// A thin lens: rays leave a disc of radius `radius` (scene units) across the view and meet on
/// the plane `focus_distance` along it, which is in focus.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lens {
    pub radius: f32,
    pub focus_distance: f32,
}

impl Lens {
    /// The height of a full-frame (35 mm) sensor, 24 mm, in metres: what an f-number's
    /// aperture is measured against, the scene's units taken as metres.
    pub const SENSOR_HEIGHT: f64 = 0.024;

    /// The aperture radius of f-number `n` for a camera of vertical field of view `fov`
    /// (degrees) on a full-frame sensor: the focal length (half the sensor height over the
    /// tangent of half the view) over twice the f-number.
    pub fn radius_of_f_number(n: f64, fov: f64) -> f64 {
        let focal = 0.5 * Self::SENSOR_HEIGHT / (0.5 * fov.to_radians()).tan();
        focal / (2.0 * n)
    }
}

/// Image size, samples per pixel, the reconstruction filter and the crop window.
#[derive(Clone, Copy, Debug)]
pub struct FilmSettings {
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    /// How a pixel weighs the film around it.
    pub pixel_filter: PixelFilter,
    /// The film this image is a window of (a Mitsuba film's crop), when it is one.
    pub window: Option<Window>,
}

impl FilmSettings {
    /// `width` x `height` at `spp`, each sample in its own pixel (a box), no crop.
    pub fn new(width: u32, height: u32, spp: u32) -> Self {
        FilmSettings { width, height, spp, pixel_filter: PixelFilter::default(), window: None }
    }
}

/// A crop: the image is the window of `width` x `height` pixels at (`x`, `y`) (from the top
/// left) of a film of `film_width` x `film_height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Window {
    pub film_width: u32,
    pub film_height: u32,
    pub x: u32,
    pub y: u32,
}

/// Steps of a filter across its radius ([`PixelFilter::eval`]): Mitsuba's `MI_FILTER_RESOLUTION`.
pub const FILTER_STEPS: usize = 31;

/// The reconstruction filter: the weight of a film position at offset `x` (in pixels, along one
/// axis; the filter is separable, as Mitsuba's) from the pixel's centre. A filter wider than
/// the pixel's own box is splatted, as Mitsuba's film splats it (`render::splat`): each sample,
/// uniform in its pixel, adds its weighted value and its weight to every pixel within reach,
/// and a pixel is the ratio. Parts split each pixel's samples, so each part splats into the
/// whole image, and a merge adds the weighted sums and the weights as it adds any sum.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PixelFilter {
    /// Weight 1 within `radius`: 0.5 (the default) is each sample in its own pixel.
    Box { radius: f32 },
    /// `max(0, 1 - |x| / radius)`; Mitsuba's default radius is 1.
    Tent { radius: f32 },
    /// `exp(-x^2 / (2 stddev^2))` less its value at the radius, 4 stddev; Mitsuba's default
    /// stddev is 0.5 (and the filter is its `hdrfilm`'s default).
    Gaussian { stddev: f32 },
}

impl Default for PixelFilter {
    fn default() -> Self {
        PixelFilter::Box { radius: 0.5 }
    }
}

impl PixelFilter {
    /// How far from a pixel's centre its samples fall, in pixels.
    pub fn radius(&self) -> f32 {
        match *self {
            PixelFilter::Box { radius } | PixelFilter::Tent { radius } => radius,
            PixelFilter::Gaussian { stddev } => 4.0 * stddev,
        }
    }

    /// The weight at offset `x` along one axis (not normalised), as Mitsuba's scalar variants
    /// evaluate their filters: the value at the nearer end of the step holding `|x|`, of
    /// [`FILTER_STEPS`] steps across the radius (`eval_discretized`), so that an image
    /// compares with Mitsuba's pixel for pixel.
    pub fn eval(&self, x: f64) -> f64 {
        let r = self.radius() as f64;
        if x.abs() >= r {
            return 0.0;
        }
        self.step_value((x.abs() / r * FILTER_STEPS as f64) as usize)
    }

    /// The value on step `k` (from 0, at the centre): the formula at the step's nearer end,
    /// `radius k / FILTER_STEPS`; 0 from the last step on.
    pub fn step_value(&self, k: usize) -> f64 {
        match k < FILTER_STEPS {
            true => self.eval_exact(self.radius() as f64 * k as f64 / FILTER_STEPS as f64),
            false => 0.0,
        }
    }

    /// The filter's own formula at `x` (`x` within the radius).
    fn eval_exact(&self, x: f64) -> f64 {
        match *self {
            PixelFilter::Box { .. } => 1.0,
            PixelFilter::Tent { radius } => (1.0 - x.abs() / radius as f64).max(0.0),
            PixelFilter::Gaussian { stddev } => {
                let r = self.radius() as f64;
                let a = -0.5 / (stddev as f64 * stddev as f64);
                ((a * x * x).exp() - (a * r * r).exp()).max(0.0)
            }
        }
    }

    /// Whether this is the default: each sample uniform in its own pixel.
    pub fn is_pixel_box(&self) -> bool {
        *self == PixelFilter::default()
    }

    /// The filter's name and parameter, as `info` and the docs write it.
    pub fn describe(&self) -> String {
        match *self {
            PixelFilter::Box { radius } => format!("box, radius {radius}"),
            PixelFilter::Tent { radius } => format!("tent, radius {radius}"),
            PixelFilter::Gaussian { stddev } => format!("gaussian, stddev {stddev}"),
        }
    }
}

/// The roughness from which a metallic-roughness material's GGX lobe counts as a D vertex in the
/// component split (its light then goes to the filtered indirect-diffuse component), unless
/// `[render] diffuse_roughness` says otherwise: chosen by measurement (`docs/scene-format.md`,
/// "glTF files"): on `scenes/gltf-hdri.toml` (roughness 0.2, 0.35, 0.5 and 0.9), every lobe
/// counted D gave the lowest error at 16, 64 and 256 spp with the paper's box filter and with
/// the à-trous one.
pub const DIFFUSE_ROUGHNESS: f32 = 0.2;

/// Which numbers a render draws.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum SamplerKind {
    /// Independent uniform numbers: PCG32 streams.
    Independent,
    /// Owen-scrambled Sobol points, a sequence per purpose and bounce.
    #[default]
    Sobol,
}

impl SamplerKind {
    pub const ALL: [SamplerKind; 2] = [SamplerKind::Independent, SamplerKind::Sobol];

    /// The name on the command line, in scene files and in `converge`'s results.
    pub fn name(self) -> &'static str {
        match self {
            SamplerKind::Independent => "independent",
            SamplerKind::Sobol => "sobol",
        }
    }

    pub fn parse(name: &str) -> Option<SamplerKind> {
        SamplerKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl std::fmt::Display for SamplerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// How next-event estimation picks a light among many (with at most eight, every light is
/// sampled at each vertex whatever this says).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum LightSamplerKind {
    /// Every light equally likely.
    Uniform,
    /// In proportion to each light's power.
    Power,
    /// By a light tree: in proportion to a bound of what each light sends to the shading
    /// point (distance, orientation, the surface's normal); lights at infinity each sampled
    /// beside it.
    #[default]
    Tree,
}

impl LightSamplerKind {
    pub const ALL: [LightSamplerKind; 3] =
        [LightSamplerKind::Uniform, LightSamplerKind::Power, LightSamplerKind::Tree];

    /// The name on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            LightSamplerKind::Uniform => "uniform",
            LightSamplerKind::Power => "power",
            LightSamplerKind::Tree => "tree",
        }
    }

    pub fn parse(name: &str) -> Option<LightSamplerKind> {
        LightSamplerKind::ALL.into_iter().find(|k| k.name() == name)
    }
}

impl std::fmt::Display for LightSamplerKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Whether a render guides directions at diffuse-like vertices by the incident light it learns
/// ([`crate::render::guide`]), and what the guide learns from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Guiding {
    /// Not guided: the BSDF alone samples directions.
    #[default]
    Off,
    /// Guided by the light a bounce brings after a further bounce: not the light sources it
    /// finds directly, which next-event estimation samples already.
    Indirect,
    /// Guided by all the light a bounce brings.
    All,
}

impl Guiding {
    pub const ALL: [Guiding; 3] = [Guiding::Off, Guiding::Indirect, Guiding::All];

    /// The name on the command line and in scene files.
    pub fn name(self) -> &'static str {
        match self {
            Guiding::Off => "off",
            Guiding::Indirect => "indirect",
            Guiding::All => "all",
        }
    }

    /// What `true` means: the better of the two measured (on `window-room.toml`, 128x128, at
    /// equal time 0.55x and 0.58x the unguided MSE learning all the light, 0.52x and 0.56x
    /// the indirect only; with a training 30 times longer, 1.31x and 1.14x less MSE of the
    /// indirect component a sample: docs/RESULTS.md, issue 39).
    pub const ON: Guiding = Guiding::All;

    pub fn parse(name: &str) -> Option<Guiding> {
        match name {
            "true" | "on" => Some(Guiding::ON),
            "false" => Some(Guiding::Off),
            _ => Guiding::ALL.into_iter().find(|k| k.name() == name),
        }
    }
}

/// An output layer named by a light path expression ([`crate::lpe`]; `[[aov]]`, `--aov`): the
/// light of the paths the expression matches, written as the EXR layer `name.R/G/B`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Aov {
    pub name: String,
    /// The expression, a built-in's name already replaced by its expression.
    pub lpe: String,
}

impl Aov {
    /// An AOV as the command line's `--aov` takes it: `NAME=EXPR`, or the name of a built-in
    /// expression ([`Aov::new`]).
    pub fn parse(text: &str) -> Result<Aov, String> {
        match text.split_once('=') {
            Some((name, expr)) => Aov::new(name.trim(), Some(expr)),
            None => Aov::new(text.trim(), None),
        }
    }

    /// An AOV `name` of expression `lpe` (or of the built-in expression `lpe` names; `lpe`
    /// `None`: the built-in called `name`), checked: a name of letters, digits and `_` that
    /// does not start with a digit, and an expression that parses.
    pub fn new(name: &str, lpe: Option<&str>) -> Result<Aov, String> {
        if crate::filter::AovName::new(name).is_none() {
            return Err(format!(
                "AOV name `{name}`: use letters, digits and `_`, not starting with a digit, at most {} of them (it names an EXR layer)",
                crate::filter::AovName::MAX
            ));
        }
        if crate::film::layers::is_reserved(name) {
            return Err(format!("AOV `{name}`: the film has a layer of that name already"));
        }
        // Names the filter's targets and `compare --layer` take for themselves.
        if crate::filter::Target::NAMED.iter().any(|t| t.name() == name) || name == "final" {
            return Err(format!("AOV `{name}`: the name is a filter target's or the final image's"));
        }
        let lpe = match lpe {
            Some(e) => crate::lpe::builtin(e).unwrap_or(e),
            None => crate::lpe::builtin(name).ok_or_else(|| {
                let names: Vec<&str> = crate::lpe::BUILTINS.iter().map(|(n, _)| *n).collect();
                format!("`{name}` is not a built-in expression ({}); give one as NAME=EXPR", names.join(", "))
            })?,
        };
        crate::lpe::Aovs::compile(&[(name, lpe)], &[])
            .map_err(|(_, e)| format!("AOV `{name}`: light path expression `{lpe}`: {e}"))?;
        Ok(Aov { name: name.to_string(), lpe: lpe.to_string() })
    }
}

/// Path length limit and the random seed.
#[derive(Clone, Copy, Debug)]
pub struct RenderSettings {
    /// The most scattering events a path may have (1 = direct light only).
    pub max_depth: u32,
    pub seed: u64,
    /// Which numbers the paths draw.
    pub sampler: SamplerKind,
    /// How next-event estimation picks a light.
    pub light_sampler: LightSamplerKind,
    /// Whether directions are guided by the learned incident light.
    pub guiding: Guiding,
}

/// How a surface scatters light.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian reflection with the given albedo (a D vertex in the paper's notation).
    Diffuse { albedo: Vec3 },
    /// Perfect specular reflection, tinted by `color` (an S vertex).
    Mirror { color: Vec3 },
    /// A smooth dielectric: Fresnel reflection and refraction with index `ior` (an S vertex).
    Glass { ior: f32, color: Vec3 },
    /// A GGX microfacet lobe with reflectance `specular` at normal incidence and `roughness` in
    /// [0, 1] (the renderer's GGX alpha is its square; an S vertex), over a diffuse `base` (a D
    /// vertex; black for none).
    Glossy { specular: Vec3, roughness: f32, base: Vec3 },
    /// glTF's metallic-roughness material: a GGX lobe over a diffuse base, `metallic` blending
    /// the lobe's reflectance at normal incidence from 0.04 (a dielectric) to `base_color` (a
    /// conductor) and the base from `base_color` to black. The GGX lobe is an S vertex below
    /// roughness `diffuse_from` and a D vertex from it up; the base is always D.
    Pbr { base_color: Vec3, metallic: f32, roughness: f32, diffuse_from: f32 },
    /// glTF's metallic-roughness material with its layers (specular, ior, transmission,
    /// clearcoat, sheen): [`crate::render::bsdf::Principled`].
    Layered(Box<Layered>),
    /// Mitsuba's `conductor` and `roughconductor` ([`crate::render::bsdf::Conductor`]).
    Conductor(Box<ConductorMaterial>),
    /// Mitsuba's `dielectric` and `thindielectric` ([`crate::render::bsdf::Dielectric`]).
    Dielectric(Box<DielectricMaterial>),
    /// Mitsuba's `plastic` and `roughplastic` ([`crate::render::bsdf::Plastic`]).
    Plastic(Box<PlasticMaterial>),
    /// A material that scatters from its front only (the side the geometric normal points
    /// to) and is black from behind: a Mitsuba BSDF outside a `twosided`.
    Front(Box<Material>),
    /// Mitsuba's `blendbsdf`: `(1 - weight) a + weight b`, one of the two chosen at each hit
    /// with those probabilities (as a blend cut-out chooses: by a hash of the hit), which is
    /// the blend in expectation.
    Blend(Box<BlendMaterial>),
}

/// glTF's layered material: metallic-roughness and the layers of its material extensions.
#[derive(Clone, Debug, PartialEq)]
pub struct Layered {
    pub base_color: Vec3,
    pub metallic: f32,
    pub roughness: f32,
    /// The roughness from which the specular lobe and the clearcoat count as diffuse.
    pub diffuse_from: f32,
    pub layers: Layers,
}

/// The factors of glTF's material extensions, as one layered BSDF reads them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layers {
    /// The dielectric's reflectance at normal incidence and at grazing
    /// (`KHR_materials_specular`, `KHR_materials_ior`).
    pub f0: Vec3,
    pub f90: f32,
    /// The index of refraction transmitted light bends by.
    pub ior: f32,
    /// The fraction of the dielectric's base transmitted instead of diffused.
    pub transmission: f32,
    /// Thin-walled (`KHR_materials_volume` absent or of thickness 0): transmitted light goes
    /// straight through.
    pub thin: bool,
    /// Beer-Lambert absorption inside a closed transmissive object (not thin), per unit of
    /// distance in the scene: -ln(attenuation colour) / attenuation distance. Zero: clear.
    pub absorption: Vec3,
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    pub sheen_color: Vec3,
    pub sheen_roughness: f32,
    /// `KHR_materials_specular`'s factor and colour, which `f0` and `f90` are made of (kept
    /// for its textures, which multiply them).
    pub specular: f32,
    pub specular_color: Vec3,
}

impl Default for Layers {
    /// No layer: glTF's plain metallic-roughness dielectric (index 1.5).
    fn default() -> Self {
        Layers {
            f0: Vec3::splat(0.04),
            f90: 1.0,
            ior: 1.5,
            transmission: 0.0,
            thin: true,
            absorption: Vec3::ZERO,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            sheen_color: Vec3::ZERO,
            sheen_roughness: 0.0,
            specular: 1.0,
            specular_color: Vec3::ONE,
        }
    }
}

/// Triangles shared with the accelerators without copying. `positions` is 16 bytes a vertex
/// (`Vec3A`), the layout Embree reads in place.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub positions: Arc<[Vec3A]>,
    pub indices: Arc<[[u32; 3]]>,
    /// Per-vertex shading normals, when the mesh file has them.
    pub normals: Option<Arc<[Vec3]>>,
    /// Per-vertex texture coordinates (quads have them; OBJ files may).
    pub uvs: Option<Arc<[Vec2]>>,
    /// A glTF mesh's other vertex attributes, when it has any.
    pub attributes: Option<Box<Attributes>>,
    /// For a mesh shared by several shapes (a glTF mesh used by several nodes): the vertices
    /// above are in the mesh's own coordinates, and this places them in the scene. The
    /// accelerators trace the mesh once, in its own coordinates (Embree instances, the BVH's
    /// second level); [`Mesh::triangle`] gives the placed corners.
    pub instance: Option<Box<Instance>>,
    /// The vertices in the scene file's own coordinates (f64, not camera-relative), kept only
    /// where the mesh's material reads a solid texture: [`Scene::solid_point`] interpolates them,
    /// so a plane that lies on a checker's cell boundary reads the same cell in every sample.
    pub world: Option<Arc<[DVec3]>>,
}

/// A mesh's vertex attributes beyond positions, normals and the first texture coordinates (a
/// glTF's), each one a vertex when present.
#[derive(Clone, Debug, Default)]
pub struct Attributes {
    /// A second set of texture coordinates (`TEXCOORD_1`, v up), for textures that name it.
    pub uv1: Option<Arc<[Vec2]>>,
    /// Vertex colours (`COLOR_0`, linear RGB), multiplying the base colour.
    pub colors: Option<Arc<[Vec3]>>,
    /// Tangents (`TANGENT`, in the mesh's coordinates) and, in w, the sign of the bitangent
    /// (`cross(normal, tangent) * w`): the frame of the normal map.
    pub tangents: Option<Arc<[glam::Vec4]>>,
    /// Vertex alpha (`COLOR_0`'s fourth component), multiplying the material's alpha; kept
    /// only where the material has an alpha mode.
    pub alpha: Option<Arc<[f32]>>,
}

/// Where a shared mesh is placed: an affine map from its own coordinates into the scene's that
/// does not mirror (a mirrored placement gets its own copy, so geometric normals stay outward).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    pub to_world: Affine3A,
    pub to_local: Affine3A,
    /// The map of normals (the inverse transpose of the linear part).
    pub normals: Mat3A,
    /// How much the map magnifies rounding error: the product of the largest row sums of the
    /// absolute linear part and of its inverse (1 for a rotation with a uniform scale, up to
    /// rounding; more when the map shears or stretches).
    pub condition: f32,
}

impl Instance {
    /// The placement by `to_world`, or `None` when it mirrors, is singular or is not finite.
    pub fn new(to_world: Affine3A) -> Option<Instance> {
        let m = to_world.matrix3;
        let det = m.determinant();
        if !to_world.is_finite() || det <= 0.0 || !det.is_normal() {
            return None;
        }
        let to_local = to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let norm = |m: Mat3A| {
            let t = m.transpose();
            t.x_axis.abs().element_sum().max(t.y_axis.abs().element_sum()).max(t.z_axis.abs().element_sum())
        };
        Some(Instance {
            to_world,
            to_local,
            normals: m.inverse().transpose(),
            condition: (norm(m) * norm(to_local.matrix3)).max(1.0),
        })
    }

    /// The error magnitude (see [`crate::math::offset_ray_origin`]) of a point computed from
    /// these local corners: what the placed corners' coordinates are made of, magnified by the
    /// trip of the next ray back into the mesh's coordinates.
    pub fn magnitude(&self, local: [Vec3; 3]) -> f32 {
        let m = self.to_world.matrix3;
        let abs = Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        let corner = |p: Vec3| abs * Vec3A::from(p.abs()) + self.to_world.translation.abs();
        let most = corner(local[0]).max(corner(local[1])).max(corner(local[2])).max_element();
        most * self.condition
    }
}

impl Mesh {
    /// A mesh of these triangles, in the scene's coordinates.
    pub fn new(
        positions: Arc<[Vec3A]>,
        indices: Arc<[[u32; 3]]>,
        normals: Option<Arc<[Vec3]>>,
        uvs: Option<Arc<[Vec2]>>,
    ) -> Mesh {
        Mesh { positions, indices, normals, uvs, attributes: None, instance: None, world: None }
    }

    /// Per-vertex `values` interpolated at barycentrics `(u, v)` of triangle `prim`.
    #[inline(always)]
    pub fn interpolate<T>(&self, values: &[T], prim: u32, (u, v): (f32, f32)) -> T
    where
        T: Copy + std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
    {
        let [a, b, c] = self.indices[prim as usize].map(|i| values[i as usize]);
        a * (1.0 - u - v) + b * u + c * v
    }

    /// The texture coordinates of set `set` (0 or 1), when the mesh has them.
    #[inline]
    pub fn uvs(&self, set: u8) -> Option<&[Vec2]> {
        match set {
            0 => self.uvs.as_deref(),
            _ => self.attributes.as_ref().and_then(|a| a.uv1.as_deref()),
        }
    }

    /// Texture coordinates `set` (0 or 1) at barycentrics `bary` of triangle `prim`, when the
    /// mesh has them.
    #[inline]
    pub fn uv(&self, set: u8, prim: u32, bary: (f32, f32)) -> Option<Vec2> {
        self.uvs(set).map(|t| self.interpolate(t, prim, bary))
    }

    /// The three corners of triangle `prim`, placed in the scene.
    #[inline]
    pub fn triangle(&self, prim: u32) -> [Vec3; 3] {
        let local = self.local_triangle(prim);
        match &self.instance {
            None => local,
            Some(i) => local.map(|p| i.to_world.transform_point3(p)),
        }
    }

    /// Vertex `k`, placed in the scene.
    #[inline]
    pub fn vertex(&self, k: u32) -> Vec3 {
        let p = self.positions[k as usize];
        match &self.instance {
            None => p.into(),
            Some(i) => i.to_world.transform_point3a(p).into(),
        }
    }

    /// The three corners of triangle `prim` in the mesh's own coordinates (the scene's, unless
    /// the mesh is an instance).
    #[inline]
    pub fn local_triangle(&self, prim: u32) -> [Vec3; 3] {
        let [a, b, c] = self.indices[prim as usize];
        [
            self.positions[a as usize].into(),
            self.positions[b as usize].into(),
            self.positions[c as usize].into(),
        ]
    }

    /// The error magnitude of a point on triangle `prim` (see
    /// [`crate::math::offset_ray_origin`]), from its placed corners.
    #[inline]
    pub fn magnitude(&self, prim: u32, placed: [Vec3; 3]) -> f32 {
        let [a, b, c] = placed;
        let own = crate::math::triangle_magnitude(a, b, c);
        match &self.instance {
            None => own,
            Some(i) => own.max(i.magnitude(self.local_triangle(prim))),
        }
    }

    /// Which vertex and triangle arrays the mesh holds: equal for meshes that share them (the
    /// accelerators build one structure for all instances of a mesh).
    pub fn arrays(&self) -> (usize, usize) {
        (
            Arc::as_ptr(&self.positions) as *const Vec3A as usize,
            Arc::as_ptr(&self.indices) as *const [u32; 3] as usize,
        )
    }

    /// Twice the area of each triangle would do for sampling; this is the area itself.
    pub fn triangle_area(&self, prim: u32) -> f32 {
        let [a, b, c] = self.triangle(prim);
        0.5 * (b - a).cross(c - a).length()
    }
}

/// A shape's geometry: an analytic sphere or a triangle mesh.
#[derive(Clone, Debug)]
pub enum Geometry {
    Sphere { center: Vec3, radius: f32 },
    Triangles(Mesh),
}

/// One shape of the scene: geometry, material, optional emission and the object it belongs to.
#[derive(Clone, Debug)]
pub struct Shape {
    pub name: String,
    pub geometry: Geometry,
    pub material: u32,
    /// Emitted radiance on the front side (zero when the shape is not a light).
    pub emission: Vec3,
    /// Index into [`Scene::objects`]: what the object-ID buffer shows.
    pub object: u32,
}

impl Shape {
    pub fn is_emissive(&self) -> bool {
        self.emission.max_element() > 0.0
    }
}

/// Light groups (`light_group = "name"` on a light or a shape): named sets of lights and
/// emissive shapes, whose light path expressions name them as labels (`L'name'`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightGroups {
    /// The groups: a scene file's `[[light]]` tables' first, then its shapes', in file order
    /// (a glTF file's: its emissive materials', then its lights').
    pub names: Vec<String>,
    /// (index in [`Scene::lights`], index in `names`), by light.
    pub lights: Vec<(u32, u32)>,
    /// (index in [`Scene::shapes`], index in `names`), by shape.
    pub shapes: Vec<(u32, u32)>,
}

impl LightGroups {
    /// The index of group `name`, added when new: a name from a file that is not a valid one
    /// ([`LightGroups::check_name`]) has its quotes as `_`, and no name is `light`.
    pub fn group(&mut self, name: &str) -> u32 {
        let name = match name.replace('\'', "_") {
            n if n.is_empty() => "light".to_string(),
            n => n,
        };
        let name = name.as_str();
        match self.names.iter().position(|n| n == name) {
            Some(i) => i as u32,
            None => {
                self.names.push(name.to_string());
                self.names.len() as u32 - 1
            }
        }
    }

    /// The group of light `i`.
    pub fn of_light(&self, i: u32) -> Option<u32> {
        self.lights.iter().find(|(l, _)| *l == i).map(|(_, g)| *g)
    }

    /// The group of shape `i`.
    pub fn of_shape(&self, i: u32) -> Option<u32> {
        self.shapes.iter().find(|(s, _)| *s == i).map(|(_, g)| *g)
    }

    /// Whether `name` can name a group: not empty, no `'` (it is quoted in expressions).
    pub fn check_name(name: &str) -> Result<(), String> {
        if name.is_empty() || name.contains('\'') {
            return Err(format!("light group `{name}`: a name must not be empty or hold `'`"));
        }
        Ok(())
    }

    /// One AOV a group (`--light-groups`): `group_NAME` (other characters than letters, digits
    /// and `_` as `_`), the light of the group's emitters along every path, `C.*[LO]'NAME'`.
    pub fn aovs(&self) -> Result<Vec<Aov>, String> {
        let mut out: Vec<Aov> = Vec::new();
        for name in &self.names {
            let clean: String =
                name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
            let mut layer = format!("group_{clean}");
            while out.iter().any(|a| a.name == layer) {
                layer.push('_');
            }
            out.push(Aov::new(&layer, Some(&format!("C.*[LO]'{name}'")))?);
        }
        Ok(out)
    }
}

/// A light that is not a shape.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity `intensity` (W/sr) from a point.
    Point { position: Vec3, intensity: Vec3 },
    /// A distant disc of directions around `direction` (unit, towards the sun) whose solid angle
    /// is `2 pi one_minus_cos`; `radiance` gives the irradiance the scene file asked for.
    Sun { direction: Vec3, radiance: Vec3, one_minus_cos: f32, diffuse_source: bool },
    /// Constant radiance from every direction at infinity.
    Sky { radiance: Vec3, diffuse_source: bool },
    /// Radiance at infinity from a latitude-longitude image (an HDRI).
    Environment { map: Arc<environment::EnvironmentMap>, diffuse_source: bool },
    /// The paper's cloudy sky: CIE overcast with fBm clouds.
    CloudySky { sky: sky::CloudySky, diffuse_source: bool },
    /// A point that shines `intensity` (W/sr) along `direction` (unit), fading smoothly from
    /// full at `cos_falloff_start` to nothing at `cos_total` (cosines of the angle from the axis).
    Spot { position: Vec3, direction: Vec3, intensity: Vec3, cos_total: f32, cos_falloff_start: f32 },
}

impl Light {
    /// A sun towards `direction` (need not be unit) giving `irradiance` on a surface facing it,
    /// `angular_diameter` degrees across: its cone's 1 - cos(half angle) in f64, about 2e-5 for
    /// the real sun, which f32 cannot hold as a difference from 1.
    pub fn sun(direction: Vec3, irradiance: Vec3, angular_diameter: f64, diffuse_source: bool) -> Light {
        let half = (angular_diameter / 2.0).to_radians();
        let one_minus_cos = 2.0 * (half / 2.0).sin().powi(2);
        let solid_angle = 2.0 * std::f64::consts::PI * one_minus_cos;
        Light::Sun {
            direction: direction.normalize_or_zero(),
            radiance: irradiance / solid_angle as f32,
            one_minus_cos: one_minus_cos as f32,
            diffuse_source,
        }
    }

    /// The fraction of a spot light's intensity sent at angle `cos` (cosine) from its axis:
    /// 1 inside the inner cone, 0 outside the outer, a smoothstep between (as pbrt-v4 does).
    pub fn spot_falloff(cos: f32, cos_total: f32, cos_falloff_start: f32) -> f32 {
        if cos >= cos_falloff_start {
            return 1.0;
        }
        if cos <= cos_total {
            return 0.0;
        }
        let t = (cos - cos_total) / (cos_falloff_start - cos_total);
        t * t * (3.0 - 2.0 * t)
    }
}

/// A loaded scene, ready to be traced.
#[derive(Clone, Debug)]
pub struct Scene {
    pub path: PathBuf,
    /// Every file the scene was read from: the scene file, its meshes and image textures (no
    /// output may overwrite one).
    pub inputs: Vec<PathBuf>,
    /// Where the scene's coordinates start, in the world of the scene file: every point of the
    /// scene (shapes, lights, the camera) is stored relative to it, in f32. A scene file's
    /// origin is its camera's position, subtracted in f64 before rounding, so precision around
    /// the camera does not depend on how far the world puts it.
    pub origin: glam::DVec3,
    pub camera: Camera,
    pub film: FilmSettings,
    pub render: RenderSettings,
    pub materials: Vec<Material>,
    pub shapes: Vec<Shape>,
    pub lights: Vec<Light>,
    /// Object names; a shape's `object` indexes this.
    pub objects: Vec<String>,
    /// The names of the materials that have one (by index in `materials`): the scene file's,
    /// a glTF file's, an OBJ's `.mtl` names, a Mitsuba file's BSDF ids. [`Scene::material_name`]
    /// names the rest.
    pub material_names: Vec<(u32, String)>,
    /// The scene's own `[filter]` section, as written (`filter::Setting::of_scene` reads it; the
    /// command line can override it).
    pub filter: Option<FilterSection>,
    pub textures: Vec<texture::Texture>,
    /// For each material (by index; missing means none), the textures it reads.
    pub maps: Vec<Maps>,
    /// What a user should know of how the scene was read (what was left out, what was assumed),
    /// one line each: the commands print them.
    pub notes: Vec<String>,
    /// The parameters the file was read with (`-D name=value` of a Mitsuba file), which a run
    /// key counts as the files are.
    pub parameters: Vec<(String, String)>,
    /// The output layers of light path expressions the file names (`[[aov]]`).
    pub aovs: Vec<Aov>,
    /// Which lights and emissive shapes are in which named group.
    pub light_groups: LightGroups,
}

/// The textures a material reads instead of its constants.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Maps {
    /// The albedo of a diffuse material, or the base of a glossy one.
    pub color: Option<u32>,
    /// A solid texture read as a height field of this amplitude.
    pub bump: Option<(u32, f32)>,
    /// A metallic-roughness material's texture: roughness in green, metallic in blue,
    /// multiplying its factors.
    pub metal_rough: Option<u32>,
    /// A tangent-space normal map (linear RGB, +x along the texture's u, +y along its v) and
    /// the scale of its x and y.
    pub normal: Option<(u32, f32)>,
    /// An image read as a height field over the texture coordinates (its luminance, times the
    /// scale, in scene units): an OBJ's `map_Bump`.
    pub height: Option<(u32, f32)>,
    /// A layered material's transmission texture: its red channel multiplies the factor.
    pub transmission: Option<u32>,
    /// An emissive texture (an image, sRGB-decoded) multiplying the emission of the shapes of
    /// the material.
    pub emission: Option<u32>,
    /// A specular-glossiness material's texture: its colour multiplying the dielectric's f0,
    /// and (the second texture, its alpha) the glossiness, 1 - roughness.
    pub spec_gloss: Option<(u32, u32)>,
    /// The textures of the layered material's extensions.
    pub layer: LayerMaps,
    /// Where the surface is cut out: its alpha ([`cutout`]).
    pub alpha: Option<cutout::Alpha>,
}

/// The textures of glTF's material extensions, each multiplying its factor: the clearcoat's
/// (red) and its roughness's (green), the sheen colour's (sRGB) and its roughness's (alpha),
/// the specular factor's (alpha) and the specular colour's (sRGB).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LayerMaps {
    pub clearcoat: Option<u32>,
    pub clearcoat_roughness: Option<u32>,
    pub sheen_color: Option<u32>,
    pub sheen_roughness: Option<u32>,
    pub specular: Option<u32>,
    pub specular_color: Option<u32>,
    /// The clearcoat's own tangent-space normal map and its scale (as [`Maps::normal`]).
    pub clearcoat_normal: Option<(u32, f32)>,
}

impl LayerMaps {
    pub const NONE: LayerMaps = LayerMaps {
        clearcoat: None,
        clearcoat_roughness: None,
        sheen_color: None,
        sheen_roughness: None,
        specular: None,
        specular_color: None,
        clearcoat_normal: None,
    };

    pub fn count(&self) -> usize {
        [
            self.clearcoat,
            self.clearcoat_roughness,
            self.sheen_color,
            self.sheen_roughness,
            self.specular,
            self.specular_color,
            self.clearcoat_normal.map(|(t, _)| t),
        ]
        .iter()
        .flatten()
        .count()
    }
}

impl Maps {
    /// A material without textures.
    pub const NONE: Maps = Maps {
        color: None,
        bump: None,
        metal_rough: None,
        normal: None,
        height: None,
        transmission: None,
        emission: None,
        spec_gloss: None,
        layer: LayerMaps::NONE,
        alpha: None,
    };

    /// Whether these maps read a solid texture of `textures` (as the colour or the bump).
    pub fn read_solid(&self, textures: &[texture::Texture]) -> bool {
        [self.color, self.bump.map(|(t, _)| t)]
            .into_iter()
            .flatten()
            .any(|t| textures.get(t as usize).is_some_and(texture::Texture::is_solid))
    }
}

impl Scene {
    /// The name of every material, by index: its own ([`Scene::material_names`]), else
    /// `material<m>`.
    pub fn material_name_list(&self) -> Vec<std::borrow::Cow<'_, str>> {
        let mut out: Vec<std::borrow::Cow<'_, str>> =
            (0..self.materials.len()).map(|m| format!("material{m}").into()).collect();
        for (m, name) in &self.material_names {
            if let Some(slot) = out.get_mut(*m as usize) {
                *slot = name.as_str().into();
            }
        }
        out
    }

    /// What shape `shape` emits at texture coordinates `uvs` (the first set and the second):
    /// its emission, times its material's emissive texture there.
    #[inline(always)]
    pub fn emission_at(&self, shape: &Shape, uvs: [Vec2; 2]) -> Vec3 {
        match self.maps(shape.material).emission.map(|t| &self.textures[t as usize]) {
            Some(t) => shape.emission * t.color(DVec3::ZERO, uvs[t.set() as usize]),
            None => shape.emission,
        }
    }

    /// The mean emission of shape `shape` (its emissive texture's mean over the image), for
    /// choosing among the lights by their power.
    pub fn mean_emission(&self, shape: &Shape) -> Vec3 {
        match self.maps(shape.material).emission.map(|t| &self.textures[t as usize]) {
            Some(texture::Texture::Image { image, .. }) => shape.emission * image.mean(),
            _ => shape.emission,
        }
    }

    /// The absorption per unit distance inside an object of material `m`, when it absorbs.
    #[inline(always)]
    pub fn absorption(&self, m: u32) -> Option<Vec3> {
        match self.materials.get(m as usize) {
            Some(Material::Layered(l)) if !l.layers.thin && l.layers.absorption != Vec3::ZERO => {
                Some(l.layers.absorption)
            }
            _ => None,
        }
    }

    /// The textures material `m` reads.
    /// Material `m`'s maps, by reference: a hit reads them on the path from the intersection
    /// to the BSDF, and a copy is some 140 bytes.
    #[inline(always)]
    pub fn maps(&self, m: u32) -> &Maps {
        self.maps.get(m as usize).unwrap_or(&Maps::NONE)
    }

    /// Whether material `m` reads a solid texture (its colour or its bump): its meshes keep
    /// their vertices in f64 ([`Mesh::world`]).
    pub fn reads_solid_texture(&self, m: u32) -> bool {
        self.maps(m).read_solid(&self.textures)
    }

    /// The point at which a solid texture is read: on a mesh that keeps its vertices in f64,
    /// triangle `prim` at barycentrics `(u, v)` as `a + u (b - a) + v (c - a)` in the scene
    /// file's coordinates, so a point is exact where the geometry is (on a plane at y = 0, y is
    /// 0 in every sample, not a rounding error either side of a cell boundary); elsewhere the
    /// camera-relative point `p` plus the scene's origin.
    pub fn solid_point(&self, geometry: &Geometry, prim: u32, (u, v): (f32, f32), p: Vec3) -> DVec3 {
        if let Geometry::Triangles(Mesh { world: Some(world), indices, .. }) = geometry {
            if let Some(&[ia, ib, ic]) = indices.get(prim as usize) {
                let at = |i: u32| world.get(i as usize).copied();
                if let (Some(a), Some(b), Some(c)) = (at(ia), at(ib), at(ic)) {
                    return a + (b - a) * u as f64 + (c - a) * v as f64;
                }
            }
        }
        self.origin + p.as_dvec3()
    }
}

/// What lights a scene from infinity, as `render --environment` asks for it.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    /// A latitude-longitude HDRI (`.hdr`, `.exr` or `.pfm`), at scale 1, its light direct
    /// (an HDRI often holds a sun), as a scene file's environment light without keys.
    File(PathBuf),
    /// A uniform white sky of radiance 1: the default of a model rendered directly.
    White,
    /// Nothing at infinity: only the scene's own lights and emission.
    None,
}

impl Environment {
    /// `white`, `none`, or a file's path.
    pub fn parse(text: &str) -> Environment {
        match text {
            "white" => Environment::White,
            "none" => Environment::None,
            path => Environment::File(PathBuf::from(path)),
        }
    }
}

impl Light {
    /// Whether the light is at infinity in every direction (a sky or an environment map), as
    /// `--environment` replaces it; a sun is a light of its own.
    pub fn is_environment(&self) -> bool {
        matches!(self, Light::Sky { .. } | Light::Environment { .. } | Light::CloudySky { .. })
    }
}

impl Scene {
    /// Replaces what lights the scene from infinity (its skies and environment maps, or the
    /// default white sky of a model rendered directly) with `environment`; its other lights
    /// and its emission are kept. A file becomes one of the scene's inputs.
    pub fn set_environment(&mut self, environment: &Environment) -> Result<(), crate::error::InputError> {
        let light = match environment {
            Environment::None => None,
            Environment::White => Some(Light::Sky { radiance: Vec3::ONE, diffuse_source: true }),
            Environment::File(path) => {
                let error = |e: String| crate::error::InputError(format!("--environment: {e}"));
                limits::check_input_file(path).map_err(error)?;
                let map = environment::EnvironmentMap::load(path, 1.0, 0.0).map_err(error)?;
                self.inputs.push(path.clone());
                Some(Light::Environment { map: Arc::new(map), diffuse_source: false })
            }
        };
        // The lights kept move down over those removed: their light groups follow them.
        let mut kept = Vec::with_capacity(self.lights.len());
        for (i, l) in self.lights.iter().enumerate() {
            if !l.is_environment() {
                kept.push(i as u32);
            }
        }
        self.light_groups.lights = (self.light_groups.lights.iter())
            .filter_map(|&(l, g)| kept.iter().position(|&k| k == l).map(|n| (n as u32, g)))
            .collect();
        self.lights.retain(|l| !l.is_environment());
        self.lights.extend(light);
        Ok(())
    }

    /// The number of triangles over all meshes.
    pub fn triangle_count(&self) -> usize {
        self.shapes
            .iter()
            .map(|s| match &s.geometry {
                Geometry::Triangles(m) => m.indices.len(),
                Geometry::Sphere { .. } => 0,
            })
            .sum()
    }

    /// Refuses a shape that reaches farther from the camera than [`limits::MAX_COORDINATE`],
    /// naming it: beyond it, f32 ray arithmetic cannot trace it.
    pub fn check_extent(&self) -> Result<(), SceneError> {
        let max = limits::MAX_COORDINATE;
        for shape in &self.shapes {
            let reach = match &shape.geometry {
                Geometry::Sphere { center, radius } => center.abs().max_element() + radius.abs(),
                Geometry::Triangles(mesh) => (0..mesh.positions.len() as u32)
                    .map(|k| mesh.vertex(k).abs().max_element())
                    .fold(0.0f32, f32::max),
            };
            // (Every coordinate is finite: the readers refuse NaN and infinities.)
            if reach > max {
                return Err(SceneError::new(
                    &self.path,
                    None,
                    format!(
                        "shape `{}` reaches {reach:.1e} from the camera, beyond the {max:e} that rays in f32 can trace: move it or scale it down",
                        shape.name
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Axis-aligned bounds of all shapes, `(min, max)`; a point at the origin when empty.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for shape in &self.shapes {
            match &shape.geometry {
                Geometry::Sphere { center, radius } => {
                    lo = lo.min(*center - Vec3::splat(*radius));
                    hi = hi.max(*center + Vec3::splat(*radius));
                }
                Geometry::Triangles(mesh) => {
                    for k in 0..mesh.positions.len() as u32 {
                        let p = mesh.vertex(k);
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                }
            }
        }
        if lo.x > hi.x {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        }
    }
}
