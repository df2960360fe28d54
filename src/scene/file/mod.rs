//! The TOML scene file: serde structs that reject unknown keys and non-finite numbers, then a
//! pass that resolves names, builds geometry and reports every problem as `file:line: message`.
//! One module per section; the format is documented in `docs/scene-format.md`.

mod filter;
mod light;
mod material;
mod settings;
mod shape;
mod texture;
mod typed;

use std::fmt;
use std::ops::Range;
use std::path::Path;

use glam::{DVec3, Vec3};
use serde::de::{self, Deserializer, IgnoredAny, Visitor};
use serde::Deserialize;
use toml::Spanned;
use toml_edit::ImDocument;

pub use filter::{FilterSection, KernelSpec};

use super::{Camera, Light, Scene, SceneError, Shape};

/// A finite number within f32's range, kept in f64: TOML's `nan` and `inf` are rejected where
/// they are written. Coordinates stay in f64 until the scene's origin is subtracted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wide(pub f64);

impl<'de> Deserialize<'de> for Wide {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Finite;
        impl Visitor<'_> for Finite {
            type Value = Wide;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a finite number")
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> Result<Wide, E> {
                self.visit_f64(v as f64)
            }
            fn visit_u64<E: de::Error>(self, v: u64) -> Result<Wide, E> {
                self.visit_f64(v as f64)
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> Result<Wide, E> {
                if !v.is_finite() {
                    Err(E::custom(format!("{v} is not a finite number")))
                } else if v.abs() > f32::MAX as f64 {
                    Err(E::custom(format!("{v} is too large for a 32-bit float")))
                } else {
                    Ok(Wide(v))
                }
            }
        }
        d.deserialize_any(Finite)
    }
}

/// A finite number (a [`Wide`] one, rounded to f32).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F(pub f32);

impl<'de> Deserialize<'de> for F {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        Wide::deserialize(d).map(|w| F(w.0 as f32))
    }
}

/// `N` finite numbers, exactly: an array with fewer or more elements (junk included) is
/// refused, not cut short.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Exact<const N: usize>(pub [Wide; N]);

impl<'de, const N: usize> Deserialize<'de> for Exact<N> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Numbers<const N: usize>;
        impl<'de, const N: usize> Visitor<'de> for Numbers<N> {
            type Value = Exact<N>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                write!(f, "an array of {N} finite numbers")
            }
            fn visit_seq<A: de::SeqAccess<'de>>(self, mut seq: A) -> Result<Exact<N>, A::Error> {
                let mut out = [Wide(0.0); N];
                for (i, slot) in out.iter_mut().enumerate() {
                    *slot = seq.next_element::<Wide>()?.ok_or_else(|| de::Error::invalid_length(i, &self))?;
                }
                if seq.next_element::<IgnoredAny>()?.is_some() {
                    return Err(de::Error::custom(format!(
                        "expected an array of {N} finite numbers, found more"
                    )));
                }
                Ok(Exact(out))
            }
        }
        d.deserialize_seq(Numbers::<N>)
    }
}

/// A point, direction or colour: three finite numbers.
type V3 = Exact<3>;

/// The vector of three finite numbers, in f32 (a direction or colour).
fn v3(v: V3) -> Vec3 {
    dv3(v).as_vec3()
}

/// The vector of three finite numbers, in f64 (a point, before the origin is subtracted).
fn dv3(Exact([x, y, z]): V3) -> DVec3 {
    DVec3::new(x.0, y.0, z.0)
}

/// The whole file. The typed sections are read table by table, after their `type` key
/// ([`typed::tables`]); they are named here so that serde accepts them, and lists them when a
/// section is unknown.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileScene {
    camera: Spanned<settings::FileCamera>,
    film: Option<settings::FileFilm>,
    render: Option<settings::FileRender>,
    #[serde(rename = "material", default)]
    _material: IgnoredAny,
    #[serde(rename = "shape", default)]
    _shape: IgnoredAny,
    #[serde(rename = "light", default)]
    _light: IgnoredAny,
    filter: Option<Spanned<FilterSection>>,
    #[serde(rename = "texture", default)]
    _texture: IgnoredAny,
    #[serde(default)]
    aov: Vec<Spanned<FileAov>>,
}

/// An `[[aov]]` table: an output layer and its light path expression (or a built-in's name).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileAov {
    name: String,
    lpe: String,
}

/// 1-based line of a byte offset.
fn line_of(text: &str, offset: usize) -> usize {
    text.as_bytes()[..offset.min(text.len())].iter().filter(|&&b| b == b'\n').count() + 1
}

/// Reports errors against one scene file.
struct Ctx<'a> {
    path: &'a Path,
    text: &'a str,
    /// The world position every point is stored relative to: the camera's.
    origin: DVec3,
    /// `[render] diffuse_roughness`, which glTF shapes' materials take.
    diffuse_roughness: f32,
}

impl Ctx<'_> {
    /// The error `message` at the line where `span` starts (no line without a span).
    fn error(&self, span: Option<Range<usize>>, message: impl Into<String>) -> SceneError {
        SceneError::new(self.path, span.map(|s| line_of(self.text, s.start)), message)
    }

    /// The error `message` at the line where `span` starts, as a result.
    fn err<T>(&self, span: Range<usize>, message: impl Into<String>) -> Result<T, SceneError> {
        Err(self.error(Some(span), message))
    }

    /// A TOML error, its message on one line.
    fn toml(&self, span: Option<Range<usize>>, message: &str) -> SceneError {
        let message: Vec<&str> = message.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        self.error(span, message.join("; "))
    }
}

/// Reads and resolves a scene file. Every problem is one [`SceneError`] naming the file and line.
pub fn load(path: &Path) -> Result<Scene, SceneError> {
    crate::scene::limits::check_scene_file(path).map_err(|e| SceneError::new(path, None, e))?;
    let text = std::fs::read_to_string(path)
        .map_err(|e| SceneError::new(path, None, format!("cannot read the scene file: {e}")))?;
    parse(path, &text)
}

/// A mesh file (`.obj` with its `.mtl`, or `.ply`) rendered by itself, as a glTF file is: the
/// mesh as one `type = "mesh"` shape, a camera framing its bounds, 640x480 at 16 spp, and the
/// default environment when it has no light (said in notes). Errors name the mesh file.
pub fn mesh_scene(path: &Path) -> Result<Scene, SceneError> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let quoted = toml_edit::Value::from(name.as_str()).to_string();
    let text = format!(
        "[camera]\nposition = [0, 0, 0]\nlook_at = [0, 0, -1]\n[film]\nwidth = 640\nheight = 480\nspp = 16\n\
         [render]\nmax_depth = 8\n[[shape]]\ntype = \"mesh\"\nfile = {quoted}\n"
    );
    // The generated text's lines mean nothing to the user: an error is the mesh's own.
    let mut scene = parse(path, &text).map_err(|e| {
        let prefix = format!("mesh `{name}`: ");
        let message = e.message.strip_prefix(&prefix).unwrap_or(&e.message).to_string();
        SceneError::new(path, None, message)
    })?;
    let (lo, hi) = scene.bounds();
    let (position, forward) = crate::scene::framing(lo.as_dvec3(), hi.as_dvec3());
    scene.camera = Camera {
        position: position.as_vec3(),
        look_at: (position + forward).as_vec3(),
        up: glam::Vec3::Y,
        fov: crate::scene::FRAMING_FOV,
        orthographic: None,
        lens: None,
    };
    scene.notes.push("no camera: framing the model's bounds from the front".into());
    if scene.lights.is_empty() {
        scene.notes.push(crate::scene::default_environment_note(scene.shapes.iter().any(Shape::is_emissive)));
        scene.lights.push(Light::Sky { radiance: glam::Vec3::ONE, diffuse_source: true });
    }
    Ok(scene)
}

/// Parses scene text as if read from `path` (relative mesh paths resolve against its directory).
pub fn parse(path: &Path, text: &str) -> Result<Scene, SceneError> {
    let ctx = Ctx { path, text, origin: DVec3::ZERO, diffuse_roughness: crate::scene::DIFFUSE_ROUGHNESS };
    let doc = ImDocument::parse(text).map_err(|e| ctx.toml(e.span(), e.message()))?;
    let file = FileScene::deserialize(toml_edit::de::Deserializer::from(doc.clone()))
        .map_err(|e| ctx.toml(e.span(), e.message()))?;
    let root = doc.as_table();
    let textures_in = typed::tables::<texture::TextureKind>(&ctx, root)?;
    let materials = typed::tables::<material::MaterialKind>(&ctx, root)?;
    let shapes = typed::tables::<shape::ShapeKind>(&ctx, root)?;
    let lights_in = typed::tables::<light::LightKind>(&ctx, root)?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();

    let (camera, origin) = settings::camera(&ctx, &file.camera)?;
    let diffuse_roughness = settings::diffuse_roughness(&ctx, file.render.as_ref())?;
    let ctx = Ctx { origin, diffuse_roughness, ..ctx };
    let film = settings::film(&ctx, file.film.as_ref())?;
    let render = settings::render(&ctx, file.render.as_ref())?;
    let (mut textures, texture_ids) = texture::textures(&ctx, &dir, &textures_in)?;
    let material::Materials { mut materials, mut maps, ids: material_ids } =
        material::materials(&ctx, &materials, &textures, &texture_ids)?;
    let mut builder = shape::Builder::default();
    builder.textures_before = textures.len() as u32;
    builder.solid = maps.iter().map(|m| m.read_solid(&textures)).collect();
    // The light groups: of each `[[light]]`, and of the emitters each `[[shape]]` adds (its
    // shapes that emit, a glTF file's lights, which follow the file's own lights).
    let mut groups = crate::scene::LightGroups::default();
    for (i, l) in lights_in.iter().enumerate() {
        if let Some(name) = &l.common.light_group {
            crate::scene::LightGroups::check_name(name).map_err(|e| ctx.error(Some(l.span.clone()), e))?;
            let g = groups.group(name);
            groups.lights.push((i as u32, g));
        }
    }
    for s in &shapes {
        let (first_shape, first_light) = (builder.shapes.len(), builder.lights.len());
        shape::add(&ctx, &dir, s, &mut materials, &material_ids, &mut builder)?;
        let named = std::mem::take(&mut builder.gltf_groups);
        if shape::light_group(s).is_none() {
            // A glTF file's own names.
            for (of, name) in named {
                let g = groups.group(&name);
                match of {
                    shape::GroupOf::Light(i) => groups.lights.push(((lights_in.len() + i) as u32, g)),
                    shape::GroupOf::Shape(i) => groups.shapes.push((i as u32, g)),
                }
            }
        }
        if let Some(name) = shape::light_group(s) {
            crate::scene::LightGroups::check_name(name).map_err(|e| ctx.error(Some(s.span.clone()), e))?;
            let g = groups.group(name);
            let before = groups.shapes.len();
            let emitting = (first_shape..builder.shapes.len()).filter(|&i| builder.shapes[i].is_emissive());
            groups.shapes.extend(emitting.map(|i| (i as u32, g)));
            let lights = first_light..builder.lights.len();
            if groups.shapes.len() == before && lights.is_empty() {
                builder.notes.push(format!("light group `{name}`: its shape emits no light"));
            }
            groups.lights.extend(lights.map(|i| ((lights_in.len() + i) as u32, g)));
        }
    }
    let mut lights = lights_in.iter().map(|l| light::light(&ctx, &dir, l)).collect::<Result<Vec<_>, _>>()?;
    // What glTF shapes brought.
    lights.append(&mut builder.lights);
    textures.append(&mut builder.textures);
    for (m, mp) in std::mem::take(&mut builder.maps) {
        if maps.len() <= m as usize {
            maps.resize(m as usize + 1, Default::default());
        }
        maps[m as usize] = mp;
    }
    let inputs = std::iter::once(path.to_path_buf())
        .chain(textures_in.iter().filter_map(|t| t.of_type.file()).map(|f| dir.join(f)))
        .chain(shapes.iter().filter_map(|s| s.of_type.file()).map(|f| dir.join(f)))
        .chain(lights_in.iter().filter_map(|l| l.of_type.file()).map(|f| dir.join(f)))
        .chain(builder.libraries)
        .collect();
    let mut aovs: Vec<crate::scene::Aov> = Vec::new();
    for a in &file.aov {
        let aov = crate::scene::Aov::new(&a.get_ref().name, Some(&a.get_ref().lpe))
            .map_err(|e| ctx.error(Some(a.span()), e))?;
        if aovs.iter().any(|b| b.name == aov.name) {
            return ctx.err(a.span(), format!("a second [[aov]] named `{}`", aov.name));
        }
        aovs.push(aov);
    }
    let filter = file.filter.map(|f| {
        let line = line_of(text, f.span().start);
        FilterSection { line, ..f.into_inner() }
    });

    let mut material_names: Vec<(u32, String)> =
        material_ids.iter().map(|(name, &m)| (m, name.clone())).collect();
    material_names.sort_unstable();
    material_names.append(&mut builder.material_names);
    Ok(Scene {
        filter,
        textures,
        maps,
        path: path.to_path_buf(),
        inputs,
        origin,
        camera,
        film,
        render,
        materials,
        shapes: builder.shapes,
        lights,
        objects: builder.objects,
        material_names,
        notes: builder.notes,
        parameters: Vec::new(),
        aovs,
        light_groups: groups,
    })
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
    fn nan_and_inf_are_rejected_where_written() {
        let text = format!("{MINIMAL}[[shape]]\ntype = \"sphere\"\nradius = nan\n");
        let (line, msg) = error_line(&text);
        assert_eq!(line, Some(6), "{msg}");
        assert!(msg.contains("finite"), "{msg}");
        let (line, msg) = error_line("[camera]\nposition = [0, inf, -5]\nlook_at = [0, 1, 0]\n");
        assert_eq!(line, Some(2), "{msg}");
    }
}
