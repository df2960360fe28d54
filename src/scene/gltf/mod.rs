//! glTF 2.0 (`.gltf` with external or embedded buffers, and `.glb`), its JSON parsed by the `gltf`
//! crate and its bytes read by [`data`]: the default scene's node hierarchy with its transforms,
//! triangle meshes with indices, normals, two sets of texture coordinates, vertex colours and
//! tangents, textures through their samplers (wrap modes, nearest or bilinear), the
//! metallic-roughness materials with their textures and emission (its texture a texture), the material extensions
//! of one layered BSDF (specular, ior, transmission, volume, clearcoat, sheen;
//! specular-glossiness converted: [`layers`]), its perspective and orthographic cameras (the first, or the one
//! `render --camera` names), `KHR_lights_punctual` lights,
//! `KHR_materials_emissive_strength` and `KHR_texture_transform`. Meshes come out in their own
//! coordinates, read once, with each node's transform into the glTF's world (f64); the rest
//! comes out in that world. [`crate::scene::file`] and [`scene`] place it in a scene, where a
//! mesh that several nodes use is shared (instanced), not copied.
//!
//! Not read (yet): occlusion, alpha modes, mipmaps, iridescence and the rest (named in a note
//! when a file uses them), skins, morph targets, animations, points and lines. The volume's thickness texture is not read by design: a path tracer traces the
//! geometry the thickness stands for.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

mod data;

use glam::{Affine2, DMat3, DMat4, DVec3, DVec4, Vec2, Vec3, Vec3A};

use crate::scene::cutout::{Alpha, AlphaMode};
use crate::scene::image::Image;
use crate::scene::texture::{Sampling, Texture, Wrap};
use crate::scene::{
    Attributes, Camera, FilmSettings, Geometry, Instance, LayerMaps, Layered, Layers, Light, Maps, Material,
    Mesh, RenderSettings, Scene, SceneError, Shape,
};
use data::Buffers;
use gltf::mesh::{Mode, Semantic};

/// Photometric to radiometric units: glTF lights are in candela (point, spot) and lux
/// (directional); a watt of light at 555 nm is 683 lumens, the ratio Blender's importer uses.
pub const LUMENS_PER_WATT: f32 = 683.0;

/// One triangle mesh primitive in its mesh's own coordinates, read once however many nodes use
/// it.
#[derive(Clone, Debug)]
pub struct Primitive {
    /// `mesh/primitive`, for messages and shape names.
    pub name: String,
    pub positions: Arc<[Vec3A]>,
    pub indices: Arc<[[u32; 3]]>,
    pub normals: Option<Arc<[Vec3]>>,
    /// Texture coordinates with v up (glTF's v runs down the image; it is flipped here).
    pub uvs: Option<Arc<[Vec2]>>,
    /// The second texture coordinates, vertex colours and tangents, when it has any.
    pub attributes: Option<Box<Attributes>>,
    /// Index into [`Gltf::materials`]; `None` is glTF's default material.
    pub material: Option<usize>,
    /// How many nodes place it.
    pub uses: usize,
}

/// A primitive placed by a node.
#[derive(Clone, Debug)]
pub struct NodePrimitive {
    /// `node/mesh/primitive` names, for messages and the object-ID buffer.
    pub name: String,
    /// The node's name (the object it belongs to).
    pub node: String,
    /// Index into [`Gltf::primitives`].
    pub primitive: usize,
    /// The node's transform into the glTF's world.
    pub world: DMat4,
}

impl NodePrimitive {
    /// The part's vertices in the glTF's world.
    pub fn positions<'a>(&'a self, g: &'a Gltf) -> impl Iterator<Item = DVec3> + 'a {
        g.primitives[self.primitive].positions.iter().map(|p| self.world.transform_point3(p.as_dvec3()))
    }
}

/// A metallic-roughness material: factors, and textures as indices into [`Gltf::images`].
#[derive(Clone, Debug, PartialEq)]
pub struct PbrMaterial {
    pub name: String,
    pub base_color: Vec3,
    /// Base colour texture, sRGB-decoded: multiplies `base_color`.
    pub base_color_texture: Option<usize>,
    pub metallic: f32,
    pub roughness: f32,
    /// Linear: roughness in G, metallic in B, multiplying the factors.
    pub metallic_roughness_texture: Option<usize>,
    /// Emitted radiance: the factor (times `KHR_materials_emissive_strength`), which the
    /// emissive texture multiplies.
    pub emission: Vec3,
    /// sRGB-decoded, multiplying `emission`.
    pub emissive_texture: Option<usize>,
    /// `KHR_materials_unlit`: it emits its base colour (`emission`) and reflects nothing.
    pub unlit: bool,
    /// A specular-glossiness material's texture, as two: its colour (sRGB) multiplying f0, and
    /// its alpha (linear) multiplying the glossiness.
    pub spec_gloss_texture: Option<(usize, usize)>,
    /// The extensions' textures (indices into [`Gltf::textures`]).
    pub layer: LayerMaps,
    /// A tangent-space normal map (linear) and its scale.
    pub normal_texture: Option<(usize, f32)>,
    /// The material extensions' layers, when it has any.
    pub layers: Option<Layers>,
    /// Linear: the transmitted fraction in R, multiplying the transmission factor.
    pub transmission_texture: Option<usize>,
    /// `alphaMode` MASK or BLEND: the base colour's alpha (its texture an index into
    /// [`Gltf::textures`], the base colour texture's alpha channel).
    pub alpha: Option<Alpha>,
}

impl Default for PbrMaterial {
    /// glTF's default material: white, fully metallic and rough.
    fn default() -> Self {
        PbrMaterial {
            name: "default".into(),
            base_color: Vec3::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            metallic_roughness_texture: None,
            emission: Vec3::ZERO,
            normal_texture: None,
            layers: None,
            transmission_texture: None,
            emissive_texture: None,
            unlit: false,
            spec_gloss_texture: None,
            layer: LayerMaps::default(),
            alpha: None,
        }
    }
}

/// A camera, placed by its node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GltfCamera {
    pub position: DVec3,
    pub forward: DVec3,
    pub up: DVec3,
    /// Vertical field of view, degrees.
    pub fov: f32,
    pub aspect: Option<f32>,
    /// An orthographic camera's view height (twice its `ymag`), in the glTF's world.
    pub orthographic: Option<f64>,
}

/// A `KHR_lights_punctual` light, placed by its node, in radiometric units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PunctualLight {
    /// Irradiance (W/m^2) arriving along `direction` (the way the light travels).
    Directional { direction: DVec3, irradiance: Vec3 },
    /// Radiant intensity (W/sr).
    Point { position: DVec3, intensity: Vec3 },
    /// Radiant intensity (W/sr) inside the inner cone; angles in radians.
    Spot { position: DVec3, direction: DVec3, intensity: Vec3, inner: f32, outer: f32 },
}

/// A glTF file read.
#[derive(Clone, Debug)]
pub struct Gltf {
    pub primitives: Vec<Primitive>,
    pub parts: Vec<NodePrimitive>,
    pub materials: Vec<PbrMaterial>,
    /// Images by texture use: each image decoded to linear RGB from linear or sRGB values, or its
    /// alpha channel alone.
    pub images: Vec<Arc<Image>>,
    /// Textures: an image of [`Gltf::images`], the transform of its (u, v) ([`uv_transform`])
    /// and its sampler; the materials' textures index these.
    pub textures: Vec<(usize, Option<Affine2>, Sampling)>,
    /// The cameras (perspective and orthographic) in the order of the node hierarchy, each named by its camera's
    /// name, else its node's.
    pub cameras: Vec<(String, GltfCamera)>,
    pub lights: Vec<PunctualLight>,
    /// Each light's name (its node's when it has none): its light group.
    pub light_names: Vec<String>,
    /// The external files it read (buffers, images), besides itself.
    pub files: Vec<PathBuf>,
    /// What was left out, one line each.
    pub notes: Vec<String>,
}

/// `KHR_texture_transform`'s map of glTF's (u, v) (`offset`, then `rotation` in radians, then
/// `scale`, as the extension's matrix `T R S`) in the renderer's (u, v), whose v runs up the
/// image where glTF's runs down: v flipped, mapped, flipped back.
pub fn uv_transform(offset: Vec2, rotation: f32, scale: Vec2) -> Affine2 {
    let (s, c) = rotation.sin_cos();
    // The columns (cos, -sin) and (sin, cos): the extension's GLSL matrix read as rows, as the
    // Khronos viewer applies it (TextureTransformTest's arrows point at its check marks so).
    let gltf = Affine2::from_mat2_translation(
        glam::Mat2::from_cols(Vec2::new(c, -s), Vec2::new(s, c)) * glam::Mat2::from_diagonal(scale),
        offset,
    );
    let flip =
        Affine2::from_mat2_translation(glam::Mat2::from_diagonal(Vec2::new(1.0, -1.0)), Vec2::new(0.0, 1.0));
    flip * gltf * flip
}

/// `KHR_texture_transform` of a texture: offset (u, v), rotation, scale (u, v), and the
/// texture coordinates it names, if any.
#[derive(Clone, Copy, Debug)]
struct Transform {
    values: [f32; 5],
    tex_coord: Option<u32>,
}

impl Transform {
    /// The crate's reading of it.
    fn of(t: Option<gltf::texture::TextureTransform>) -> Option<Transform> {
        t.map(|t| Transform {
            values: [t.offset()[0], t.offset()[1], t.rotation(), t.scale()[0], t.scale()[1]],
            tex_coord: t.tex_coord(),
        })
    }

    /// Its reading from the JSON of a texture info the crate does not know (an extension's).
    fn of_json(info: &serde_json::Value) -> Option<Transform> {
        let t = info.get("extensions")?.get("KHR_texture_transform")?;
        let pair = |key: &str, default: [f32; 2]| -> [f32; 2] {
            let a = t.get(key).and_then(|v| v.as_array());
            let at =
                |i: usize, d: f32| a.and_then(|a| a.get(i)).and_then(|v| v.as_f64()).map_or(d, |v| v as f32);
            [at(0, default[0]), at(1, default[1])]
        };
        let ([ox, oy], [sx, sy]) = (pair("offset", [0.0, 0.0]), pair("scale", [1.0, 1.0]));
        let rotation = t.get("rotation").and_then(|v| v.as_f64()).map_or(0.0, |v| v as f32);
        let tex_coord = t.get("texCoord").and_then(|v| v.as_u64()).map(|k| k as u32);
        Some(Transform { values: [ox, oy, rotation, sx, sy], tex_coord })
    }
}

/// How an image is decoded for a texture: its colour linear or from sRGB, or its alpha.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Decode {
    Linear,
    Srgb,
    Alpha,
}

/// How a texture's sampler reads it, with texture coordinates `set`: its wrap modes, and nearest
/// lookup when its magnification filter says so (the minification filter is not read: a lookup
/// is one texel or four, with no mipmap). A set past 1 is noted, and the first set read.
fn sampling(texture: &gltf::Texture, set: u32, notes: &mut Vec<String>) -> Sampling {
    use gltf::texture::{MagFilter, WrappingMode};
    let wrap = |w: WrappingMode| match w {
        WrappingMode::ClampToEdge => Wrap::Clamp,
        WrappingMode::MirroredRepeat => Wrap::Mirror,
        WrappingMode::Repeat => Wrap::Repeat,
    };
    let sampler = texture.sampler();
    if set > 1 {
        notes.push(format!("a texture reads TEXCOORD_{set}, not read: TEXCOORD_0 is used"));
    }
    Sampling {
        wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
        nearest: sampler.mag_filter() == Some(MagFilter::Nearest),
        set: (set == 1) as u8,
    }
}

/// The extensions read (the others a file uses are named in a note).
const READ_EXTENSIONS: &[&str] = &[
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_materials_clearcoat",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_volume",
    "KHR_texture_transform",
];

/// The extensions read here from the material's JSON, which the `gltf` crate does not know (it
/// refuses a file that requires them, so they are taken off the required list first).
const READ_RAW: &[&str] = &["KHR_materials_clearcoat", "KHR_materials_sheen"];

/// The refusal of a file that requires a compression lightsplit does not decode, saying what to
/// do instead; `None` for any other extension.
fn compressed_refusal(extension: &str) -> Option<String> {
    let (what, instead) = match extension {
        "KHR_draco_mesh_compression" => (
            "compressed meshes",
            "write it with uncompressed meshes first (Blender's glTF importer reads it; export it again without compression)",
        ),
        "KHR_texture_basisu" => (
            "KTX2 (Basis Universal) textures",
            "convert its textures to PNG first, for example with `gltf-transform ktxdecompress IN OUT`",
        ),
        _ => return None,
    };
    Some(format!("it requires `{extension}` ({what}), which lightsplit does not decode: {instead}"))
}

/// Reads a glTF or GLB file. Every problem is one message: what is wrong, and where in the file
/// (which buffer, accessor, mesh or primitive).
pub fn load(path: &Path) -> Result<Gltf, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("cannot read it: {e}"))?;
    if bytes.is_empty() {
        return Err("the file is empty (0 bytes)".into());
    }
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| format!("not valid glTF: {e}"))?;
    // The crate's validation reads a primitive's POSITION accessor before it checks that the
    // accessor exists (and panics if it does not): that one index is checked first.
    let mut json = document.into_json();
    if let Some(refusal) = json.extensions_required.iter().find_map(|e| compressed_refusal(e)) {
        return Err(refusal);
    }
    json.extensions_required
        .retain(|e| !READ_RAW.contains(&e.as_str()) && e != "KHR_mesh_quantization" && e != data::MESHOPT);
    for (m, mesh) in json.meshes.iter().enumerate() {
        for (k, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, a) in &primitive.attributes {
                if a.value() >= json.accessors.len() {
                    return Err(format!(
                        "not valid glTF: mesh {m} primitive {k}: attribute {semantic:?} names accessor {}, of {}",
                        a.value(),
                        json.accessors.len()
                    ));
                }
            }
        }
    }
    let document = gltf::Document::from_json(json).map_err(|e| format!("not valid glTF: {e}"))?;
    let base = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let root = document.as_json();
    let mut buffers = Buffers::load(root, blob, base)?;
    let mut notes = Vec::new();
    // An extension the file uses but does not require, and that is not read, is named: the
    // model renders without it (one it requires and is not read, the crate refuses).
    let unread: Vec<&str> =
        root.extensions_used.iter().map(String::as_str).filter(|e| !READ_EXTENSIONS.contains(e)).collect();
    if !unread.is_empty() {
        notes.push(format!("extensions not read (the model renders without them): {}", unread.join(", ")));
    }

    // Images: decoded when a material first uses them, once per colour space.
    let mut images: Vec<Arc<Image>> = Vec::new();
    let mut image_ids: HashMap<(usize, Decode), usize> = HashMap::new();
    let mut image_of = |texture: gltf::Texture, decode: Decode| -> Result<(usize, Arc<Image>), String> {
        let source = texture.source().index();
        if let Some(&id) = image_ids.get(&(source, decode)) {
            return Ok((id, images[id].clone()));
        }
        let image = match decode {
            Decode::Linear => buffers.image(source, false),
            Decode::Srgb => buffers.image(source, true),
            Decode::Alpha => buffers.image_alpha(source),
        };
        let image = Arc::new(image.map_err(|e| format!("image {source}: {e}"))?);
        images.push(image.clone());
        image_ids.insert((source, decode), images.len() - 1);
        Ok((images.len() - 1, image))
    };

    // Textures: an image and the transform of its (u, v), once per pair.
    let mut textures: Vec<(usize, Option<Affine2>, Sampling)> = Vec::new();
    let mut texture_of = |texture: gltf::Texture,
                          transform: Option<Transform>,
                          tex_coord: u32,
                          decode: Decode,
                          notes: &mut Vec<String>|
     -> Result<(usize, Arc<Image>), String> {
        let sampling = sampling(&texture, transform.and_then(|t| t.tex_coord).unwrap_or(tex_coord), notes);
        let (image, pixels) = image_of(texture, decode)?;
        let transform = match transform {
            None => None,
            Some(t) => {
                if !t.values.iter().all(|v| v.is_finite()) {
                    return Err("a texture transform that is not finite".into());
                }
                let [ox, oy, rotation, sx, sy] = t.values;
                Some(uv_transform(Vec2::new(ox, oy), rotation, Vec2::new(sx, sy)))
            }
        };
        let key = (image, transform, sampling);
        let at = match textures.iter().position(|k| *k == key) {
            Some(at) => at,
            None => {
                textures.push(key);
                textures.len() - 1
            }
        };
        Ok((at, pixels))
    };

    // A texture the crate reads for a material: its image, transform and coordinates.
    macro_rules! texture_info {
        ($t:expr, $decode:expr) => {
            texture_of(
                $t.texture(),
                Transform::of($t.texture_transform()),
                $t.tex_coord(),
                $decode,
                &mut notes,
            )
            .map(|t| t.0)
        };
    }

    // A texture info from an extension's JSON (material `name`'s `key`, in messages).
    macro_rules! json_texture {
        ($info:expr, $name:expr, $key:expr, $decode:expr) => {{
            let info = $info;
            let index = info.get("index").and_then(|v| v.as_u64()).map(|i| i as usize);
            let Some(texture) = index.and_then(|i| document.textures().nth(i)) else {
                return Err(format!(
                    "material `{}`: `{}` names no texture (it has {})",
                    $name,
                    $key,
                    document.textures().len()
                ));
            };
            let k = info.get("texCoord").and_then(|v| v.as_u64()).unwrap_or(0) as u32;
            texture_of(texture, Transform::of_json(info), k, $decode, &mut notes)?.0
        }};
    }

    let mut materials = Vec::new();
    let mut unread_parts = Vec::new();
    for m in document.materials() {
        let pbr = m.pbr_metallic_roughness();
        let name = m.name().map_or_else(|| format!("material{}", m.index().unwrap_or(0)), str::to_string);
        let spec_gloss = m.pbr_specular_glossiness();
        let [r, g, b, a] = match &spec_gloss {
            Some(sg) => sg.diffuse_factor(),
            None => pbr.base_color_factor(),
        };
        let color_texture = match &spec_gloss {
            Some(sg) => sg.diffuse_texture(),
            None => pbr.base_color_texture(),
        };
        let base_color_texture =
            color_texture.as_ref().map(|t| texture_info!(t, Decode::Srgb)).transpose()?;
        // The base colour's alpha, for the modes that read it: its factor, and the texture's
        // alpha channel read as a texture of its own.
        let alpha = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => None,
            mode => {
                let mode = match mode {
                    gltf::material::AlphaMode::Mask => {
                        let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                        if !cutoff.is_finite() || cutoff < 0.0 {
                            return Err(format!("material `{name}`: an alpha cutoff of {cutoff}"));
                        }
                        AlphaMode::Mask(cutoff)
                    }
                    _ => AlphaMode::Blend,
                };
                let texture = color_texture.as_ref().map(|t| texture_info!(t, Decode::Alpha)).transpose()?;
                Some(Alpha { mode, factor: a, texture: texture.map(|t| t as u32) })
            }
        };
        let (metallic, roughness, layers) = layers(&m, &name, &mut unread_parts)?;
        // The specular-glossiness texture: the specular colour in RGB (sRGB), the glossiness in
        // alpha (linear), read as two textures.
        let spec_gloss_texture =
            match m.pbr_specular_glossiness().and_then(|sg| sg.specular_glossiness_texture()) {
                Some(t) => {
                    let k = t.tex_coord();
                    let color = texture_of(
                        t.texture(),
                        Transform::of(t.texture_transform()),
                        k,
                        Decode::Srgb,
                        &mut notes,
                    )?
                    .0;
                    Some((
                        color,
                        texture_of(
                            t.texture(),
                            Transform::of(t.texture_transform()),
                            k,
                            Decode::Alpha,
                            &mut notes,
                        )?
                        .0,
                    ))
                }
                None => None,
            };
        // The extensions' textures: the crate reads the specular ones, the JSON the others.
        let mut layer = LayerMaps::default();
        if let Some(sp) = m.specular() {
            for (t, decode, slot) in [
                (sp.specular_texture(), Decode::Alpha, &mut layer.specular),
                (sp.specular_color_texture(), Decode::Srgb, &mut layer.specular_color),
            ] {
                if let Some(t) = t {
                    let tt = Transform::of(t.texture_transform());
                    *slot = Some(texture_of(t.texture(), tt, t.tex_coord(), decode, &mut notes)?.0 as u32);
                }
            }
        }
        for (ext, key, decode, slot) in [
            ("KHR_materials_clearcoat", "clearcoatTexture", Decode::Linear, &mut layer.clearcoat),
            (
                "KHR_materials_clearcoat",
                "clearcoatRoughnessTexture",
                Decode::Linear,
                &mut layer.clearcoat_roughness,
            ),
            ("KHR_materials_sheen", "sheenColorTexture", Decode::Srgb, &mut layer.sheen_color),
            ("KHR_materials_sheen", "sheenRoughnessTexture", Decode::Alpha, &mut layer.sheen_roughness),
        ] {
            let Some(info) = m.extension_value(ext).and_then(|e| e.get(key)) else { continue };
            *slot = Some(json_texture!(info, name, key, decode) as u32);
        }
        // The clearcoat's normal map, with its scale.
        let coat = m.extension_value("KHR_materials_clearcoat");
        if let Some(info) = coat.and_then(|e| e.get("clearcoatNormalTexture")) {
            let scale = info.get("scale").and_then(|v| v.as_f64()).unwrap_or(1.0) as f32;
            if !scale.is_finite() {
                return Err(format!("material `{name}`: a clearcoat normal map scale that is not finite"));
            }
            layer.clearcoat_normal =
                Some((json_texture!(info, name, "clearcoatNormalTexture", Decode::Linear) as u32, scale));
        }
        let transmission_texture = m
            .transmission()
            .and_then(|t| t.transmission_texture())
            .map(|t| texture_info!(t, Decode::Linear))
            .transpose()?;
        let metallic_roughness_texture =
            pbr.metallic_roughness_texture().map(|t| texture_info!(t, Decode::Linear)).transpose()?;
        // `KHR_materials_emissive_strength` scales the factor (and the texture) past 1.
        let strength = m.emissive_strength().unwrap_or(1.0);
        let mut emission = Vec3::from(m.emissive_factor()) * strength;
        let mut emissive_texture = match m.emissive_texture() {
            // A texture under a black factor emits nothing: not read.
            Some(t) if emission.max_element() > 0.0 => Some(
                texture_of(
                    t.texture(),
                    Transform::of(t.texture_transform()),
                    t.tex_coord(),
                    Decode::Srgb,
                    &mut notes,
                )?
                .0,
            ),
            _ => None,
        };
        // `KHR_materials_unlit`: the base colour (and its texture) is what is seen, emitted by a
        // surface that reflects nothing.
        let unlit = m.unlit();
        if unlit {
            (emission, emissive_texture) = (Vec3::new(r, g, b), base_color_texture);
        }
        let unit = |v: f32| v.is_finite() && (0.0..=1.0).contains(&v);
        if ![r, g, b, metallic, roughness].into_iter().all(unit) {
            return Err(format!("material `{name}`: a colour, metallic or roughness factor outside [0, 1]"));
        }
        if !emission.is_finite() || emission.min_element() < 0.0 {
            return Err(format!("material `{name}`: a negative or non-finite emissive factor"));
        }
        if emission.max_element() > crate::scene::limits::MAX_EMISSION {
            return Err(format!(
                "material `{name}`: an emission of {:e}, over the {:e} a surface may emit",
                emission.max_element(),
                crate::scene::limits::MAX_EMISSION
            ));
        }
        let normal_texture = match m.normal_texture() {
            Some(t) if !t.scale().is_finite() => {
                return Err(format!("material `{name}`: a normal map scale that is not finite"))
            }
            Some(t) => {
                // The crate keeps a normal texture's extensions as JSON.
                let json =
                    m.index().and_then(|i| root.materials.get(i)).and_then(|j| j.normal_texture.as_ref());
                let transform = json
                    .and_then(|n| n.extensions.as_ref())
                    .and_then(|e| Transform::of_json(&serde_json::json!({ "extensions": e.others })));
                (texture_of(t.texture(), transform, t.tex_coord(), Decode::Linear, &mut notes)?.0, t.scale())
                    .into()
            }
            None => None,
        };
        materials.push(PbrMaterial {
            name,
            base_color: Vec3::new(r, g, b),
            base_color_texture,
            metallic,
            roughness,
            metallic_roughness_texture,
            emission,
            normal_texture,
            layers,
            transmission_texture,
            emissive_texture,
            unlit,
            spec_gloss_texture,
            layer,
            alpha,
        });
    }

    gather_notes(&unread_parts, &mut notes);
    let scene = document.default_scene().or_else(|| document.scenes().next()).ok_or("it has no scene")?;
    let mut out = Gltf {
        primitives: Vec::new(),
        parts: Vec::new(),
        materials,
        images,
        textures,
        cameras: Vec::new(),
        lights: Vec::new(),
        light_names: Vec::new(),
        files: Vec::new(),
        notes,
    };
    // Each mesh's primitives, read the first time a node uses it.
    let mut read: HashMap<usize, std::ops::Range<usize>> = HashMap::new();
    check_trees(&document, &scene)?;
    // Depth first, in the document's order (the stack holds what is left in reverse). The
    // nodes form trees (checked above), so each is visited once.
    let mut stack: Vec<(gltf::Node, DMat4)> = scene.nodes().map(|n| (n, DMat4::IDENTITY)).collect();
    stack.reverse();
    while let Some((node, parent)) = stack.pop() {
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(|x| x as f64)));
        let world = parent * local;
        if !world.is_finite() {
            return Err(format!("node {}: its transform is not finite", node.index()));
        }
        let node_name = node.name().map_or_else(|| format!("node{}", node.index()), str::to_string);
        if let Some(mesh) = node.mesh() {
            let range = match read.get(&mesh.index()) {
                Some(r) => r.clone(),
                None => {
                    let first = out.primitives.len();
                    add_mesh(&mut out, &buffers, &mesh)?;
                    read.insert(mesh.index(), first..out.primitives.len());
                    first..out.primitives.len()
                }
            };
            for p in range {
                out.primitives[p].uses += 1;
                out.parts.push(NodePrimitive {
                    name: format!("{node_name}/{}", out.primitives[p].name),
                    node: node_name.clone(),
                    primitive: p,
                    world,
                });
            }
        }
        if let Some(camera) = node.camera() {
            let name = camera.name().map_or_else(|| node_name.clone(), str::to_string);
            match camera.projection() {
                gltf::camera::Projection::Perspective(p) => {
                    let at = |v: DVec4| world * v;
                    out.cameras.push((
                        name,
                        GltfCamera {
                            position: at(DVec4::W).truncate(),
                            forward: at(DVec4::new(0.0, 0.0, -1.0, 0.0)).truncate().normalize_or_zero(),
                            up: at(DVec4::Y).truncate().normalize_or_zero(),
                            fov: p.yfov().to_degrees(),
                            aspect: p.aspect_ratio(),
                            orthographic: None,
                        },
                    ))
                }
                gltf::camera::Projection::Orthographic(o) => {
                    let at = |v: DVec4| world * v;
                    // The view's height (twice `ymag`), scaled as the node scales its y axis.
                    let up = at(DVec4::Y).truncate();
                    out.cameras.push((
                        name,
                        GltfCamera {
                            position: at(DVec4::W).truncate(),
                            forward: at(DVec4::new(0.0, 0.0, -1.0, 0.0)).truncate().normalize_or_zero(),
                            up: up.normalize_or_zero(),
                            fov: crate::scene::FRAMING_FOV,
                            aspect: (o.ymag() != 0.0).then(|| o.xmag() / o.ymag()),
                            orthographic: Some(2.0 * o.ymag() as f64 * up.length()),
                        },
                    ))
                }
            }
        }
        if let Some(light) = node.light() {
            out.lights
                .push(punctual(&light, &world).map_err(|e| format!("light of node `{node_name}`: {e}"))?);
            out.light_names.push(light.name().map_or_else(|| node_name.to_string(), str::to_string));
        }
        let first = stack.len();
        stack.extend(node.children().map(|c| (c, world)));
        stack[first..].reverse();
    }
    out.files = std::mem::take(&mut buffers.files);
    Ok(out)
}

/// One note per kind of thing not read, naming the materials (the first few) that have it.
fn gather_notes(unread: &[String], notes: &mut Vec<String>) {
    let mut by_what: Vec<(&str, Vec<&str>)> = Vec::new();
    for u in unread {
        let (what, material) = u.split_once('\0').unwrap_or((u, ""));
        match by_what.iter_mut().find(|(w, _)| *w == what) {
            Some((_, list)) => list.push(material),
            None => by_what.push((what, vec![material])),
        }
    }
    for (what, list) in by_what {
        let shown: Vec<String> = list.iter().take(3).map(|m| format!("`{m}`")).collect();
        let more = if list.len() > 3 { format!(" and {} more", list.len() - 3) } else { String::new() };
        notes.push(format!("not read: {what}, of material {}{more}", shown.join(", ")));
    }
}

/// A number of an extension's JSON object: `default` when absent, an error naming the material
/// when not a finite number in `range`.
fn number(
    object: &serde_json::Value,
    key: &str,
    default: f32,
    range: std::ops::RangeInclusive<f32>,
    name: &str,
) -> Result<f32, String> {
    match object.get(key) {
        None => Ok(default),
        Some(v) => match v.as_f64().map(|v| v as f32) {
            Some(v) if v.is_finite() && range.contains(&v) => Ok(v),
            _ => Err(format!(
                "material `{name}`: `{key}` is {v}, not a number in [{}, {}]",
                range.start(),
                range.end()
            )),
        },
    }
}

/// A colour of an extension's JSON object (three numbers in [0, 1]), `default` when absent.
fn color(object: &serde_json::Value, key: &str, default: Vec3, name: &str) -> Result<Vec3, String> {
    let Some(v) = object.get(key) else { return Ok(default) };
    let c: Option<Vec<f32>> = v
        .as_array()
        .filter(|a| a.len() == 3)
        .and_then(|a| a.iter().map(|x| x.as_f64().map(|x| x as f32)).collect());
    match c {
        Some(c) if c.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) => {
            Ok(Vec3::new(c[0], c[1], c[2]))
        }
        _ => Err(format!("material `{name}`: `{key}` is {v}, not three numbers in [0, 1]")),
    }
}

/// A material's metallic and roughness factors and the layers of its extensions (`None` when
/// it has none of them): `KHR_materials_specular` and `_ior` give the dielectric's Fresnel,
/// `_transmission` and `_volume` what crosses it, `_clearcoat` and `_sheen` the layers on top
/// (these two read from the JSON, which the crate does not know). A specular-glossiness
/// material is converted as Khronos' glTF-Transform converts it: its diffuse colour the base,
/// metallic 0, roughness 1 - glossiness, and its specular colour the dielectric's f0 (the
/// converter's index of 1000 and specular colour). What is not read (the extensions'
/// textures, unlit) goes to `notes` as "what\0material", gathered by [`gather_notes`].
fn layers(
    m: &gltf::Material,
    name: &str,
    notes: &mut Vec<String>,
) -> Result<(f32, f32, Option<Layers>), String> {
    let pbr = m.pbr_metallic_roughness();
    let mut layers = Layers::default();
    let mut any = false;
    let mut unread = Vec::new();
    let (mut metallic, mut roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
    if let Some(sg) = m.pbr_specular_glossiness() {
        let specular = Vec3::from(sg.specular_factor());
        let glossiness = sg.glossiness_factor();
        if !specular.is_finite() || !glossiness.is_finite() {
            return Err(format!("material `{name}`: a specular or glossiness factor that is not finite"));
        }
        (metallic, roughness) = (0.0, (1.0 - glossiness).clamp(0.0, 1.0));
        layers.f0 = specular.clamp(Vec3::ZERO, Vec3::ONE);
        any = true;
    }
    let ior = m.ior().unwrap_or(1.5);
    if !(ior.is_finite() && (1.0..=10.0).contains(&ior)) {
        return Err(format!("material `{name}`: an index of refraction of {ior}, outside [1, 10]"));
    }
    layers.ior = ior;
    if let Some(sp) = m.specular() {
        let (factor, tint) = (sp.specular_factor(), Vec3::from(sp.specular_color_factor()));
        let valid = (0.0..=1.0).contains(&factor) && tint.is_finite() && tint.min_element() >= 0.0;
        if !valid {
            return Err(format!(
                "material `{name}`: a specular factor outside [0, 1] or a negative specular colour"
            ));
        }
        (layers.f0, layers.f90) = crate::render::bsdf::dielectric_f0(ior, factor, tint);
        (layers.specular, layers.specular_color) = (factor, tint);
        any = true;
    } else if m.pbr_specular_glossiness().is_none() && m.ior().is_some() {
        (layers.f0, layers.f90) = crate::render::bsdf::dielectric_f0(ior, 1.0, Vec3::ONE);
        any = true;
    }
    if let Some(t) = m.transmission() {
        let factor = t.transmission_factor();
        if !(factor.is_finite() && (0.0..=1.0).contains(&factor)) {
            return Err(format!("material `{name}`: a transmission factor outside [0, 1]"));
        }
        layers.transmission = factor;
        any = true;
    }
    if let Some(v) = m.volume() {
        let thickness = v.thickness_factor();
        if !(thickness.is_finite() && thickness >= 0.0) {
            return Err(format!("material `{name}`: a negative or non-finite volume thickness"));
        }
        layers.thin = thickness == 0.0;
        let (distance, color) = (v.attenuation_distance(), Vec3::from(v.attenuation_color()));
        if distance.is_nan() || distance <= 0.0 || !color.is_finite() || color.min_element() < 0.0 {
            return Err(format!("material `{name}`: an attenuation distance that is not positive or a negative attenuation colour"));
        }
        if distance.is_finite() {
            // -ln(c) / d per channel; a channel of colour 0 absorbs everything (a large finite
            // coefficient keeps the arithmetic finite).
            layers.absorption =
                color.max(Vec3::splat(1e-6)).min(Vec3::ONE).to_array().map(|c| -c.ln() / distance).into();
        }
    }
    if let Some(c) = m.extension_value("KHR_materials_clearcoat") {
        layers.clearcoat = number(c, "clearcoatFactor", 0.0, 0.0..=1.0, name)?;
        layers.clearcoat_roughness = number(c, "clearcoatRoughnessFactor", 0.0, 0.0..=1.0, name)?;
        any |= layers.clearcoat > 0.0;
    }
    if let Some(sh) = m.extension_value("KHR_materials_sheen") {
        layers.sheen_color = color(sh, "sheenColorFactor", Vec3::ZERO, name)?;
        layers.sheen_roughness = number(sh, "sheenRoughnessFactor", 0.0, 0.0..=1.0, name)?;
        any |= layers.sheen_color.max_element() > 0.0;
    }
    if m.unlit() {
        unread.push(
            "unlit as Blender shows it to the camera alone (it emits its base colour and reflects nothing)",
        );
    }
    for what in unread {
        notes.push(format!("{what}\u{0}{name}"));
    }
    Ok((metallic, roughness, any.then_some(layers)))
}

/// Checks that the nodes form disjoint trees, as glTF requires, before they are walked: no node
/// is its own child or the child of two nodes, and the scene's roots have no parent and are
/// listed once. A cycle (which would never end) or a node shared by several parents (whose
/// placements multiply with each level: 2^40 of them from 40 nodes) is one error naming the
/// node, found in time linear in the file.
fn check_trees(document: &gltf::Document, scene: &gltf::Scene) -> Result<(), String> {
    let mut parent: Vec<Option<usize>> = vec![None; document.nodes().len()];
    for node in document.nodes() {
        for child in node.children() {
            let (n, c) = (node.index(), child.index());
            if c == n {
                return Err(format!("node {n} is its own child"));
            }
            if let Some(p) = parent[c] {
                return Err(format!(
                    "node {c} is a child of both node {p} and node {n} (glTF nodes form trees)"
                ));
            }
            parent[c] = Some(n);
        }
    }
    // With one parent at most, a cycle has no root: it would show as a root with a parent, or
    // not at all (a cycle no root reaches is never walked).
    let mut listed = vec![false; parent.len()];
    for root in scene.nodes() {
        let r = root.index();
        if let Some(p) = parent[r] {
            return Err(format!("node {r} is a root of the scene and a child of node {p}"));
        }
        if std::mem::replace(&mut listed[r], true) {
            return Err(format!("node {r} is listed twice among the scene's roots"));
        }
    }
    Ok(())
}

/// A light in the world of its node.
fn punctual(light: &gltf::khr_lights_punctual::Light, world: &DMat4) -> Result<PunctualLight, String> {
    let power = Vec3::from(light.color()) * light.intensity() / LUMENS_PER_WATT;
    if !power.is_finite() || power.min_element() < 0.0 {
        return Err("a negative or non-finite colour or intensity".into());
    }
    let position = (*world * DVec4::W).truncate();
    let direction = (*world * DVec4::new(0.0, 0.0, -1.0, 0.0)).truncate().normalize_or_zero();
    let directed = !matches!(light.kind(), gltf::khr_lights_punctual::Kind::Point);
    if directed && direction == DVec3::ZERO {
        return Err("its node's transform leaves it no direction (a zero scale)".into());
    }
    Ok(match light.kind() {
        gltf::khr_lights_punctual::Kind::Directional => {
            PunctualLight::Directional { direction, irradiance: power }
        }
        gltf::khr_lights_punctual::Kind::Point => PunctualLight::Point { position, intensity: power },
        gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            if !(0.0..=std::f32::consts::FRAC_PI_2).contains(&outer_cone_angle)
                || !(0.0..=outer_cone_angle).contains(&inner_cone_angle)
            {
                return Err("spot cone angles outside 0 <= inner <= outer <= pi / 2".into());
            }
            PunctualLight::Spot {
                position,
                direction,
                intensity: power,
                inner: inner_cone_angle,
                outer: outer_cone_angle,
            }
        }
    })
}

/// Adds a mesh's triangle primitives, in its own coordinates, to `out.primitives`.
fn add_mesh(out: &mut Gltf, buffers: &Buffers, mesh: &gltf::Mesh) -> Result<(), String> {
    use gltf::json::accessor::{ComponentType as C, Type};
    let mesh_name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), str::to_string);
    for (k, primitive) in mesh.primitives().enumerate() {
        let here = format!("mesh `{mesh_name}` primitive {k}");
        let mode = primitive.mode();
        if !matches!(mode, Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
            out.notes.push(format!("{here}: {mode:?} are not rendered"));
            continue;
        }
        let attribute = |semantic: Semantic| primitive.get(&semantic).map(|a| a.index());
        let position = attribute(Semantic::Positions).ok_or(format!("{here}: no positions"))?;
        let floats = |a: usize, what: &str, dims: Type, types: &[C]| {
            buffers.floats(a, what, dims, types).map_err(|e| format!("{here}: {e}"))
        };
        // KHR_mesh_quantization: integer positions, normals, tangents and signed texture
        // coordinates too (the base specification has floats, and unsigned normalized
        // coordinates).
        let q = buffers.quantized();
        let (vectors, signed): (&[C], &[C]) = match q {
            true => (&[C::F32, C::I8, C::U8, C::I16, C::U16], &[C::F32, C::I8, C::I16]),
            false => (&[C::F32], &[C::F32]),
        };
        let coordinates: &[C] = match q {
            true => &[C::F32, C::U8, C::U16, C::I8, C::I16],
            false => &[C::F32, C::U8, C::U16],
        };
        let positions = floats(position, "POSITION", Type::Vec3, vectors)?;
        if let Some(i) = positions.iter().position(|x| !x.is_finite()) {
            return Err(format!("{here}: position {} is not finite (NaN or infinite)", i / 3));
        }
        let n = positions.len() / 3;
        let list: Vec<u32> = match primitive.indices() {
            Some(a) => buffers.indices(a.index()).map_err(|e| format!("{here}: {e}"))?,
            None => (0..n as u32).collect(),
        };
        if let Some(&bad) = list.iter().find(|&&i| i as usize >= n) {
            return Err(format!("{here}: index {bad} is out of range ({n} vertices)"));
        }
        let indices: Vec<[u32; 3]> = match mode {
            Mode::Triangles => {
                if !list.len().is_multiple_of(3) {
                    return Err(format!(
                        "{here}: {} indices (or vertices) do not make whole triangles (a multiple of 3)",
                        list.len()
                    ));
                }
                list.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect()
            }
            Mode::TriangleStrip => (2..list.len())
                .map(|i| {
                    if i % 2 == 0 {
                        [list[i - 2], list[i - 1], list[i]]
                    } else {
                        [list[i - 1], list[i - 2], list[i]]
                    }
                })
                .collect(),
            _ => (2..list.len()).map(|i| [list[0], list[i - 1], list[i]]).collect(),
        };
        if indices.is_empty() {
            return Err(format!("{here}: {} indices (or vertices) draw no triangle", list.len()));
        }
        let normals = match attribute(Semantic::Normals) {
            Some(a) => {
                let ns = floats(a, "NORMAL", Type::Vec3, signed)?;
                if ns.len() != 3 * n || ns.iter().any(|x| !x.is_finite()) {
                    return Err(format!("{here}: its normals are not one finite vector a vertex"));
                }
                Some(ns.chunks_exact(3).map(|v| Vec3::new(v[0], v[1], v[2]).normalize_or_zero()).collect())
            }
            None => None,
        };
        // Texture coordinates, v flipped up.
        let read_uvs = |set: u32| -> Result<Option<Arc<[Vec2]>>, String> {
            let Some(a) = attribute(Semantic::TexCoords(set)) else { return Ok(None) };
            let t = floats(a, &format!("TEXCOORD_{set}"), Type::Vec2, coordinates)?;
            if t.len() != 2 * n || t.iter().any(|x| !x.is_finite()) {
                return Err(format!("{here}: its TEXCOORD_{set} are not one finite pair a vertex"));
            }
            Ok(Some(t.chunks_exact(2).map(|t| Vec2::new(t[0], 1.0 - t[1])).collect()))
        };
        let (uvs, uv1) = (read_uvs(0)?, read_uvs(1)?);
        // Vertex colours: RGB or RGBA, floats or normalized integers; the alpha is kept where
        // the material has an alpha mode and some vertex is not opaque.
        let mut alpha = None;
        let with_alpha = primitive.material().alpha_mode() != gltf::material::AlphaMode::Opaque;
        let colors = match primitive.get(&Semantic::Colors(0)) {
            Some(a) => {
                let dims = if a.dimensions() == Type::Vec3 { Type::Vec3 } else { Type::Vec4 };
                let c = floats(a.index(), "COLOR_0", dims, &[C::F32, C::U8, C::U16])?;
                let k = dims.multiplicity();
                if c.len() != k * n || c.iter().any(|x| !x.is_finite() || *x < 0.0) {
                    return Err(format!(
                        "{here}: its COLOR_0 are not one finite, non-negative colour a vertex"
                    ));
                }
                if k == 4 && with_alpha && c.chunks_exact(4).any(|c| c[3] < 1.0) {
                    alpha = Some(c.chunks_exact(4).map(|c| c[3].min(1.0)).collect());
                }
                Some(c.chunks_exact(k).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
            }
            None => None,
        };
        let tangents = match attribute(Semantic::Tangents) {
            Some(a) => {
                let t = floats(a, "TANGENT", Type::Vec4, signed)?;
                if t.len() != 4 * n || t.iter().any(|x| !x.is_finite()) {
                    return Err(format!("{here}: its tangents are not one finite vector a vertex"));
                }
                Some(t.chunks_exact(4).map(|t| glam::Vec4::new(t[0], t[1], t[2], t[3])).collect())
            }
            None => None,
        };
        let attributes = (uv1.is_some() || colors.is_some() || tangents.is_some() || alpha.is_some())
            .then(|| Box::new(Attributes { uv1, colors, tangents, alpha }));
        let material = primitive.material().index();
        if material.is_some_and(|m| m >= out.materials.len()) {
            return Err(format!("{here}: no material {}", material.unwrap_or(0)));
        }
        out.primitives.push(Primitive {
            name: format!("{mesh_name}/{k}"),
            positions: positions.chunks_exact(3).map(|p| Vec3A::new(p[0], p[1], p[2])).collect(),
            indices: indices.into(),
            normals,
            uvs,
            attributes,
            material,
            uses: 0,
        });
    }
    Ok(())
}

/// Where a glTF's world goes in a scene: a linear map and a translation (in the scene file's
/// world), and the scene's origin, subtracted before rounding to f32.
#[derive(Clone, Copy, Debug)]
pub struct Placement {
    pub linear: DMat3,
    pub translate: DVec3,
    pub origin: DVec3,
}

impl Placement {
    pub fn point(&self, p: DVec3) -> Vec3 {
        (self.linear * p + self.translate - self.origin).as_vec3()
    }

    /// A direction (unit), turned.
    pub fn direction(&self, d: DVec3) -> Vec3 {
        (self.linear * d).normalize_or_zero().as_vec3()
    }
}

/// A glTF's shapes, materials (with their maps), textures and lights, ready to append to a
/// scene whose materials and textures so far number `first_material` and `first_texture`.
#[derive(Default)]
pub struct Placed {
    pub shapes: Vec<Shape>,
    pub materials: Vec<Material>,
    /// The glTF materials' names, by material index in the scene.
    pub material_names: Vec<(u32, String)>,
    /// Maps by material index in the scene.
    pub maps: Vec<(u32, Maps)>,
    pub textures: Vec<Texture>,
    pub lights: Vec<Light>,
    /// The light group of each light (its name) and of each emissive shape (its material's
    /// name), by index in `lights` and `shapes`.
    pub groups: crate::scene::LightGroups,
}

/// Places glTF `g` (named `name`) in a scene by `at`. `diffuse_from` is the roughness from which
/// a metallic-roughness material's specular lobe counts as diffuse; `object` gives the
/// object-ID of a node's name.
pub fn place(
    g: &Gltf,
    name: &str,
    at: &Placement,
    first_material: u32,
    first_texture: u32,
    diffuse_from: f32,
    object: &mut dyn FnMut(&str) -> u32,
) -> Placed {
    // Each image's mipmaps made once, however many textures read it.
    let mut mips: HashMap<usize, crate::scene::texture::Mips> = HashMap::new();
    let textures = g
        .textures
        .iter()
        .map(|&(i, transform, sampling)| {
            let mips = match sampling.nearest {
                true => Default::default(),
                false => {
                    mips.entry(i).or_insert_with(|| crate::scene::texture::Mips::of(&g.images[i])).clone()
                }
            };
            Texture::Image { image: g.images[i].clone(), repeat: Vec2::ONE, transform, sampling, mips }
        })
        .collect();
    let mut out = Placed { textures, ..Placed::default() };
    let texture = |i: usize| first_texture + i as u32;
    let default = PbrMaterial::default();
    for (k, m) in g.materials.iter().chain(std::iter::once(&default)).enumerate() {
        out.materials.push(if m.unlit {
            Material::Diffuse { albedo: Vec3::ZERO }
        } else if let Some(mut layers) = m.layers {
            // Absorption is per unit of the glTF's world: per unit of the scene, divided by the
            // placement's (mean) scale.
            layers.absorption /= at.linear.determinant().abs().cbrt().max(1e-12) as f32;
            Material::Layered(Box::new(Layered {
                base_color: m.base_color,
                metallic: m.metallic,
                roughness: m.roughness,
                diffuse_from,
                layers,
            }))
        } else {
            Material::Pbr {
                base_color: m.base_color,
                metallic: m.metallic,
                roughness: m.roughness,
                diffuse_from,
            }
        });
        let maps = Maps {
            color: m.base_color_texture.filter(|_| !m.unlit).map(texture),
            metal_rough: m.metallic_roughness_texture.map(texture),
            normal: m.normal_texture.map(|(t, scale)| (texture(t), scale)),
            transmission: m.transmission_texture.map(texture),
            emission: m.emissive_texture.map(texture),
            spec_gloss: m.spec_gloss_texture.map(|(c, a)| (texture(c), texture(a))),
            layer: {
                let t = |i: Option<u32>| i.map(|i| texture(i as usize));
                let l = &m.layer;
                LayerMaps {
                    clearcoat: t(l.clearcoat),
                    clearcoat_roughness: t(l.clearcoat_roughness),
                    sheen_color: t(l.sheen_color),
                    sheen_roughness: t(l.sheen_roughness),
                    specular: t(l.specular),
                    specular_color: t(l.specular_color),
                    clearcoat_normal: l.clearcoat_normal.map(|(i, scale)| (texture(i as usize), scale)),
                }
            },
            alpha: m.alpha.map(|a| Alpha { texture: a.texture.map(|t| texture(t as usize)), ..a }),
            ..Maps::default()
        };
        if maps != Maps::default() {
            out.maps.push((first_material + k as u32, maps));
        }
        if k < g.materials.len() {
            out.material_names.push((first_material + k as u32, m.name.clone()));
        }
    }
    let default_material = first_material + g.materials.len() as u32;
    for part in &g.parts {
        let primitive = &g.primitives[part.primitive];
        let material = primitive.material.map_or(default_material, |m| first_material + m as u32);
        let emission = primitive.material.map_or(Vec3::ZERO, |m| g.materials[m].emission);
        if let Some(m) = primitive.material.filter(|_| emission.max_element() > 0.0) {
            let group = out.groups.group(&g.materials[m].name);
            out.groups.shapes.push((out.shapes.len() as u32, group));
        }
        out.shapes.push(Shape {
            name: format!("{name}/{}", part.name),
            geometry: Geometry::Triangles(part_mesh(primitive, part, at)),
            material,
            emission,
            object: object(&format!("{name}/{}", part.node)),
        });
    }
    for (light, light_name) in g.lights.iter().zip(&g.light_names) {
        let group = out.groups.group(light_name);
        out.groups.lights.push((out.lights.len() as u32, group));
        out.lights.push(match *light {
            PunctualLight::Directional { direction, irradiance } => {
                Light::sun(-at.direction(direction), irradiance, 0.53, false)
            }
            PunctualLight::Point { position, intensity } => {
                Light::Point { position: at.point(position), intensity }
            }
            PunctualLight::Spot { position, direction, intensity, inner, outer } => Light::Spot {
                position: at.point(position),
                direction: at.direction(direction),
                intensity,
                cos_total: outer.cos(),
                cos_falloff_start: inner.cos(),
            },
        });
    }
    out
}

/// A part's mesh in the scene. A primitive that several nodes place is shared: its arrays, in
/// the mesh's coordinates, and an [`Instance`] placing them (the scene's origin subtracted in
/// f64 before the placement is rounded to f32). A primitive placed once, or by a mirroring
/// transform (whose winding must turn around to keep geometric normals outward), is copied
/// into the scene's coordinates, in f64 before rounding.
fn part_mesh(primitive: &Primitive, part: &NodePrimitive, at: &Placement) -> Mesh {
    let linear = at.linear * DMat3::from_mat4(part.world);
    let translate = at.linear * part.world.w_axis.truncate() + at.translate - at.origin;
    if primitive.uses > 1 && linear.determinant() > 0.0 {
        let to_world = glam::Affine3A::from_mat3_translation(linear.as_mat3(), translate.as_vec3());
        if let Some(instance) = Instance::new(to_world) {
            return Mesh {
                positions: primitive.positions.clone(),
                indices: primitive.indices.clone(),
                normals: primitive.normals.clone(),
                uvs: primitive.uvs.clone(),
                attributes: primitive.attributes.clone(),
                instance: Some(Box::new(instance)),
                world: None,
            };
        }
    }
    let normal_matrix = linear.inverse().transpose();
    let mut indices = primitive.indices.to_vec();
    if linear.determinant() < 0.0 {
        indices.iter_mut().for_each(|t| t.swap(1, 2));
    }
    Mesh {
        positions: primitive
            .positions
            .iter()
            .map(|p| (linear * p.as_dvec3() + translate).as_vec3a())
            .collect(),
        indices: indices.into(),
        normals: primitive.normals.as_ref().map(|ns| {
            ns.iter().map(|&n| (normal_matrix * n.as_dvec3()).normalize_or_zero().as_vec3()).collect()
        }),
        uvs: primitive.uvs.clone(),
        // Tangents turn with the linear map; a mirror turns the bitangent's sign too.
        attributes: primitive.attributes.as_ref().map(|a| {
            let linear = linear.as_mat3();
            let sign = if linear.determinant() < 0.0 { -1.0 } else { 1.0 };
            Box::new(Attributes {
                tangents: a.tangents.as_ref().map(|ts| {
                    ts.iter()
                        .map(|t| (linear * t.truncate()).normalize_or_zero().extend(t.w * sign))
                        .collect()
                }),
                ..(**a).clone()
            })
        }),
        instance: None,
        world: None,
    }
}

/// The default film of a glTF rendered directly: 640 pixels wide, as high as its camera's
/// aspect ratio says (4:3 without one).
const WIDTH: u32 = 640;

/// The cameras' names with their indices, for messages.
fn camera_names(cameras: &[(String, GltfCamera)]) -> String {
    cameras.iter().enumerate().map(|(i, (n, _))| format!("{i} `{n}`")).collect::<Vec<_>>().join(", ")
}

/// The camera `choice` names (an index from 0, or a camera's or its node's name), or the first;
/// `None` when the file has none (and none was asked for).
fn choose_camera(
    cameras: &[(String, GltfCamera)],
    choice: Option<&str>,
) -> Result<Option<GltfCamera>, String> {
    let Some(choice) = choice else { return Ok(cameras.first().map(|c| c.1)) };
    let found = match choice.parse::<usize>() {
        Ok(i) => cameras.get(i),
        Err(_) => cameras.iter().find(|(n, _)| n == choice),
    };
    match (found, cameras.is_empty()) {
        (Some(c), _) => Ok(Some(c.1)),
        (None, true) => Err(format!("--camera `{choice}`: the file has no camera")),
        (None, false) => Err(format!(
            "--camera `{choice}`: no such camera; the file has {} ({}), by index or name",
            cameras.len(),
            camera_names(cameras)
        )),
    }
}

/// A glTF file as a whole scene (`lightsplit render model.glb`): its camera (`choice`, else the
/// first), or one framing its bounds from the front (+z, glTF's forward) and a little above;
/// its lights, or with no
/// punctual light a uniform white sky of radiance 1 (its emission kept), said in
/// [`Scene::notes`] (`render --environment` changes it).
pub fn scene(path: &Path, choice: Option<&str>) -> Result<Scene, SceneError> {
    let error = |e: String| SceneError::new(path, None, e);
    crate::scene::limits::check_input_file(path).map_err(error)?;
    let g = load(path).map_err(error)?;
    let mut notes = g.notes.clone();
    let chosen = choose_camera(&g.cameras, choice).map_err(error)?;
    if choice.is_none() && g.cameras.len() > 1 {
        notes.push(format!(
            "{} cameras: rendering the first (`--camera NAME|INDEX` picks another: {})",
            g.cameras.len(),
            camera_names(&g.cameras)
        ));
    }
    let (lo, hi) = g
        .parts
        .iter()
        .flat_map(|p| p.positions(&g))
        .fold((DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)), |(lo, hi), p| {
            (lo.min(p), hi.max(p))
        });
    if g.parts.is_empty() {
        return Err(error("it has no triangles to render".into()));
    }
    let camera = chosen.unwrap_or_else(|| {
        let (position, forward) = crate::scene::framing(lo, hi);
        notes.push("no camera: framing the model's bounds from the front".into());
        GltfCamera {
            position,
            forward,
            up: DVec3::Y,
            fov: crate::scene::FRAMING_FOV,
            aspect: None,
            orthographic: None,
        }
    });
    // Both axes are unit or zero: an up along the view direction (a node whose transform turns
    // its camera's y axis onto its z axis) leaves the image's orientation undefined.
    if camera.forward.cross(camera.up).length() < 1e-6
        || !(camera.fov > 0.0 && camera.fov < 180.0)
        || camera.orthographic.is_some_and(|h| !(h.is_finite() && h > 0.0 && h < 1e30))
    {
        return Err(error(
            "its camera cannot be oriented (a zero axis, an up parallel to the view direction, a field of view outside (0, 180), or an orthographic view of no height)"
                .into(),
        ));
    }
    let origin = camera.position;
    let height = camera
        .aspect
        .filter(|a| a.is_finite() && *a > 0.0)
        .map_or(WIDTH * 3 / 4, |a| ((WIDTH as f32 / a).round() as u32).clamp(1, 8 * WIDTH));
    let at = Placement { linear: DMat3::IDENTITY, translate: DVec3::ZERO, origin };
    // Object IDs by name (a HashMap: a file may have thousands of nodes).
    let mut objects: Vec<String> = Vec::new();
    let mut ids: HashMap<String, u32> = HashMap::new();
    let mut object = |n: &str| -> u32 {
        *ids.entry(n.to_string()).or_insert_with(|| {
            objects.push(n.to_string());
            (objects.len() - 1) as u32
        })
    };
    let stem = path.file_stem().map_or_else(|| "gltf".into(), |s| s.to_string_lossy().into_owned());
    let placed = place(&g, &stem, &at, 0, 0, crate::scene::DIFFUSE_ROUGHNESS, &mut object);
    let mut lights = placed.lights;
    if lights.is_empty() {
        notes.push(crate::scene::default_environment_note(placed.shapes.iter().any(Shape::is_emissive)));
        lights.push(Light::Sky { radiance: Vec3::ONE, diffuse_source: true });
    }
    let mut maps = vec![Maps::default(); placed.materials.len()];
    for (m, mp) in placed.maps {
        maps[m as usize] = mp;
    }
    Ok(Scene {
        path: path.to_path_buf(),
        inputs: std::iter::once(path.to_path_buf()).chain(g.files.iter().cloned()).collect(),
        origin,
        camera: Camera {
            position: Vec3::ZERO,
            look_at: camera.forward.as_vec3(),
            up: camera.up.as_vec3(),
            fov: camera.fov,
            orthographic: camera.orthographic.map(|h| h as f32),
            lens: None,
        },
        film: FilmSettings::new(WIDTH, height, 16),
        render: RenderSettings {
            max_depth: 8,
            seed: 0,
            sampler: Default::default(),
            light_sampler: Default::default(),
            guiding: Default::default(),
        },
        materials: placed.materials,
        material_names: placed.material_names,
        shapes: placed.shapes,
        lights,
        objects,
        filter: None,
        textures: placed.textures,
        maps,
        notes,
        parameters: Vec::new(),
        aovs: Vec::new(),
        light_groups: placed.groups,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn near(a: Vec2, b: Vec2) -> bool {
        (a - b).abs().max_element() < 1e-6
    }

    /// `KHR_texture_transform` in the renderer's (u, v), whose v runs up where glTF's runs down.
    #[test]
    fn texture_transforms_map_gltf_coordinates_as_the_extension_says() {
        // glTF (0.25, 0.25), the renderer's (0.25, 0.75): offset by half in u, to glTF's (0.75, 0.25).
        let t = uv_transform(Vec2::new(0.5, 0.0), 0.0, Vec2::ONE);
        assert!(near(t.transform_point2(Vec2::new(0.25, 0.75)), Vec2::new(0.75, 0.75)));
        // Scale about glTF's origin, the image's top-left corner: glTF (0.5, 0.5) to (1, 1).
        let t = uv_transform(Vec2::ZERO, 0.0, Vec2::splat(2.0));
        assert!(near(t.transform_point2(Vec2::new(0.5, 0.5)), Vec2::new(1.0, 0.0)));
        // A quarter turn: glTF's (1, 0) to (0, -1), the renderer's (1, 1) to (0, 2), the way
        // TextureTransformTest's arrows point at its check marks.
        let t = uv_transform(Vec2::ZERO, std::f32::consts::FRAC_PI_2, Vec2::ONE);
        assert!(
            near(t.transform_point2(Vec2::new(1.0, 1.0)), Vec2::new(0.0, 2.0)),
            "{}",
            t.transform_point2(Vec2::ONE)
        );
        // None at all: the identity.
        let t = uv_transform(Vec2::ZERO, 0.0, Vec2::ONE);
        assert!(near(t.transform_point2(Vec2::new(0.3, 0.8)), Vec2::new(0.3, 0.8)));
    }
}
