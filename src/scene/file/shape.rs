//! `[[shape]]`: spheres, quads, boxes, OBJ/PLY meshes and the procedural terrain and teapot, each
//! under an optional transform (scale, rotate, translate), with its material, emission and the
//! object it belongs to.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{DMat3, DVec3, Vec2, Vec3, Vec3A};
use serde::Deserialize;
use toml::Spanned;

use super::typed::{Table, Typed};
use super::{dv3, line_of, v3, Ctx, F, V3};
use crate::scene::{gltf, obj, procedural, teapot, Geometry, Material, Mesh, SceneError, Shape};

/// The finest terrain: 2 x 4096^2, about 33.5 million triangles.
const MAX_TERRAIN: u32 = 4096;
/// The finest teapot tessellation: 64 * 256^2 = 4.2 million triangles.
const MAX_TEAPOT: u32 = 256;

/// The keys every shape takes.
#[derive(Deserialize)]
pub(super) struct ShapeCommon {
    name: Option<String>,
    material: Option<String>,
    object: Option<String>,
    emission: Option<V3>,
    transform: Option<FileTransform>,
    /// The light group of its emitters (its own emission, a glTF file's lights and emissive
    /// meshes).
    light_group: Option<String>,
}

/// `transform = { scale, rotate, translate }` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileTransform {
    scale: Option<F>,
    rotate: Option<V3>,
    translate: Option<V3>,
}

/// A shape's type and its own keys.
#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum ShapeKind {
    Sphere(Sphere),
    Quad(Quad),
    Box(BoxShape),
    Mesh(MeshFile),
    Gltf(GltfFile),
    Terrain(Terrain),
    Teapot(Teapot),
}

impl Typed for ShapeKind {
    type Common = ShapeCommon;
    const SECTION: &'static str = "shape";
}

/// Mesh formats that are not Wavefront OBJ, named in the error rather than read as an empty OBJ.
const OTHER_MESH_FORMATS: &[&str] =
    &["fbx", "stl", "dae", "3ds", "usd", "usda", "usdc", "usdz", "abc", "blend"];

impl ShapeKind {
    /// The file a mesh reads, as written (relative to the scene file).
    pub(super) fn file(&self) -> Option<&str> {
        match self {
            ShapeKind::Mesh(MeshFile { file }) | ShapeKind::Gltf(GltfFile { file }) => Some(file),
            _ => None,
        }
    }
}

/// An analytic sphere.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Sphere {
    center: Option<V3>,
    radius: F,
}

/// Two triangles over four corners.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Quad {
    vertices: Vec<V3>,
}

/// An axis-aligned box.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BoxShape {
    min: V3,
    max: V3,
}

/// Triangles from an OBJ or PLY file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshFile {
    file: String,
}

/// A glTF file (`.gltf`, `.glb`): its meshes, materials and lights (not its camera).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GltfFile {
    file: String,
}

/// A procedural height field.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Terrain {
    resolution: Option<Spanned<u32>>,
    size: Option<F>,
    height: Option<F>,
    seed: Option<u32>,
}

/// The Utah teapot, tessellated.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Teapot {
    resolution: Option<Spanned<u32>>,
}

/// What a light group of a glTF file holds: a light or a shape, by its index in the builder.
#[derive(Clone, Copy, Debug)]
pub(super) enum GroupOf {
    Light(usize),
    Shape(usize),
}

/// The shapes built so far and the objects they belong to.
#[derive(Default)]
pub(super) struct Builder {
    pub shapes: Vec<Shape>,
    pub objects: Vec<String>,
    object_ids: HashMap<String, u32>,
    /// The names of the materials glTF shapes and OBJ libraries bring, by material index.
    pub material_names: Vec<(u32, String)>,
    /// The material libraries the meshes read, and the files glTF shapes read (inputs of the
    /// scene).
    pub libraries: Vec<std::path::PathBuf>,
    /// The textures glTF shapes bring, numbered after the scene file's `textures_before`.
    pub textures: Vec<crate::scene::texture::Texture>,
    pub textures_before: u32,
    /// The maps of the materials glTF shapes bring, by material index.
    pub maps: Vec<(u32, crate::scene::Maps)>,
    /// The lights glTF shapes bring.
    pub lights: Vec<crate::scene::Light>,
    /// The light groups glTF files name (their lights' and emissive materials' names), by index
    /// in `lights` and `shapes` (for a shape that names none itself).
    pub gltf_groups: Vec<(GroupOf, String)>,
    /// What the user should know of how glTF shapes were read.
    pub notes: Vec<String>,
    /// By the scene file's material index, whether it reads a solid texture (its meshes keep
    /// their vertices in f64, [`Mesh::world`]).
    pub solid: Vec<bool>,
}

impl Builder {
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
/// translate; then the scene's origin is subtracted. All in f64, rounded to f32 once at the
/// end: far from the world's origin only the camera-relative position fits in f32.
struct Transform {
    linear: DMat3,
    translate: DVec3,
    origin: DVec3,
    scale: f64,
    rotates: bool,
}

impl Transform {
    fn new(t: Option<&FileTransform>, origin: DVec3) -> Self {
        let scale = t.and_then(|t| t.scale).map_or(1.0, |s| s.0 as f64);
        let r = t.and_then(|t| t.rotate).map(dv3).unwrap_or(DVec3::ZERO);
        let rotation = DMat3::from_rotation_z(r.z.to_radians())
            * DMat3::from_rotation_y(r.y.to_radians())
            * DMat3::from_rotation_x(r.x.to_radians());
        Transform {
            linear: rotation * DMat3::from_diagonal(DVec3::splat(scale)),
            translate: t.and_then(|t| t.translate).map(dv3).unwrap_or(DVec3::ZERO),
            origin,
            scale,
            rotates: r != DVec3::ZERO,
        }
    }

    /// A point of the shape in the scene file's coordinates.
    fn world(&self, p: DVec3) -> DVec3 {
        self.linear * p + self.translate
    }

    /// A point of the shape, relative to the scene's origin.
    fn point(&self, p: DVec3) -> Vec3 {
        (self.world(p) - self.origin).as_vec3()
    }

    /// Placed vertices, relative to the scene's origin, and in the scene file's coordinates
    /// too where `solid` (the material reads a solid texture; see [`Mesh::world`]).
    fn vertices(&self, p: &[DVec3], solid: bool) -> (Arc<[Vec3A]>, Option<Arc<[DVec3]>>) {
        let world: Vec<DVec3> = p.iter().map(|&q| self.world(q)).collect();
        let relative = world.iter().map(|&q| Vec3A::from((q - self.origin).as_vec3())).collect();
        (relative, solid.then(|| world.into()))
    }

    /// Normals under the transform (by the inverse transpose of the linear part).
    fn normals(&self, normals: &[Vec3]) -> Arc<[Vec3]> {
        let inv_t = self.linear.inverse().transpose();
        normals.iter().map(|&v| (inv_t * v.as_dvec3()).normalize_or_zero().as_vec3()).collect()
    }
}

/// The light group a `[[shape]]` table names for its emitters.
pub(super) fn light_group(s: &Table<ShapeKind>) -> Option<&str> {
    s.common.light_group.as_deref()
}

/// Builds one `[[shape]]` into `out` (a mesh file may give several shapes), adding the default
/// and the OBJ materials it needs to `materials`.
pub(super) fn add(
    ctx: &Ctx,
    dir: &Path,
    s: &Table<ShapeKind>,
    materials: &mut Vec<Material>,
    material_ids: &HashMap<String, u32>,
    out: &mut Builder,
) -> Result<(), SceneError> {
    let span = s.span.clone();
    let c = &s.common;
    let index = out.shapes.len();
    let name = c.name.clone().unwrap_or_else(|| format!("{}{}", s.kind, index));
    let emission = c.emission.map(v3).unwrap_or(Vec3::ZERO);
    if emission.min_element() < 0.0 {
        return ctx.err(span, "`emission` must not be negative");
    }
    if emission.max_element() > crate::scene::limits::MAX_EMISSION {
        return ctx.err(span, format!("`emission` must be at most {:e}", crate::scene::limits::MAX_EMISSION));
    }
    let transform = Transform::new(c.transform.as_ref(), ctx.origin);
    if transform.scale <= 0.0 {
        return ctx.err(span, "a transform's `scale` must be positive");
    }

    let material = match &c.material {
        Some(m) => match material_ids.get(m) {
            Some(&id) => Some(id),
            None => return ctx.err(span, format!("unknown material `{m}`")),
        },
        None => None,
    };
    let solid = material.is_some_and(|m| out.solid.get(m as usize).copied().unwrap_or(false));
    let default_material = |materials: &mut Vec<Material>| -> u32 {
        materials.push(Material::Diffuse { albedo: Vec3::splat(0.8) });
        (materials.len() - 1) as u32
    };

    let geometry = match &s.of_type {
        ShapeKind::Sphere(sphere) => {
            if transform.rotates {
                return ctx.err(span, "a sphere takes no `rotate`");
            }
            let radius = sphere.radius.0 * transform.scale as f32;
            if radius < 0.0 {
                return ctx.err(span, "a sphere's `radius` must not be negative");
            }
            let center = transform.point(sphere.center.map(dv3).unwrap_or(DVec3::ZERO));
            Geometry::Sphere { center, radius }
        }
        ShapeKind::Quad(Quad { vertices: v }) => {
            if v.len() != 4 {
                return ctx.err(span, format!("a quad needs 4 `vertices`, not {}", v.len()));
            }
            let p: Vec<DVec3> = v.iter().map(|&p| dv3(p)).collect();
            let mut quad = mesh(transform.vertices(&p, solid), &[[0, 1, 2], [0, 2, 3]]);
            // An image's bottom left, bottom right, top right and top left.
            quad.uvs = Some([Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y].into());
            Geometry::Triangles(quad)
        }
        ShapeKind::Box(b) => {
            let (lo, hi) = (dv3(b.min), dv3(b.max));
            if lo.cmpge(hi).any() {
                return ctx.err(span, "a box's `min` must be below its `max` on every axis");
            }
            let (p, i) = box_mesh(lo, hi);
            Geometry::Triangles(mesh(transform.vertices(&p, solid), &i))
        }
        ShapeKind::Mesh(MeshFile { file }) => {
            let line = Some(line_of(ctx.text, span.start));
            let path = dir.join(file);
            // Formats an OBJ reader would read as an OBJ without faces.
            let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
            if let Some(ext) = ext.as_deref().filter(|e| OTHER_MESH_FORMATS.contains(e)) {
                return ctx.err(
                    span,
                    format!(
                        "mesh `{file}`: .{ext} is not read; meshes are Wavefront OBJ files (.obj, with .mtl) or PLY files (.ply)"
                    ),
                );
            }
            if matches!(ext.as_deref(), Some("gltf" | "glb")) {
                return ctx.err(
                    span,
                    format!("mesh `{file}`: a glTF file is a shape of its own, `type = \"gltf\"`"),
                );
            }
            let ply = ext.as_deref() == Some("ply");
            let obj::Obj { parts, libraries, notes } = crate::scene::limits::check_input_file(&path)
                .and_then(|()| match ply {
                    true => crate::scene::ply::load(&path).map(|parts| obj::Obj {
                        parts,
                        libraries: Vec::new(),
                        notes: Vec::new(),
                    }),
                    false => obj::load(&path),
                })
                .map_err(|e| SceneError::new(ctx.path, line, format!("mesh `{file}`: {e}")))?;
            out.libraries.extend(libraries);
            if parts.is_empty() {
                return ctx.err(
                    span,
                    format!("mesh `{file}` has no faces (meshes are Wavefront OBJ or PLY files)"),
                );
            }
            out.notes.extend(notes);
            // Each OBJ object is a shape of its own (and an object of its own, unless the scene
            // file names one), with its .mtl material unless the scene file gives one.
            let mut images: HashMap<(std::path::PathBuf, Read), u32> = HashMap::new();
            for part in parts {
                let part_material = match (material, &part.material) {
                    (Some(id), _) => id,
                    (None, Some(m)) => {
                        materials.push(match m.dielectric {
                            Some(ior) => Material::Glass { ior, color: m.transmission },
                            None if m.specular.max_element() > 0.0 => Material::Glossy {
                                specular: m.specular,
                                roughness: m.roughness,
                                base: m.diffuse,
                            },
                            None => Material::Diffuse { albedo: m.diffuse },
                        });
                        let id = (materials.len() - 1) as u32;
                        out.material_names.push((id, m.name.clone()));
                        let mut image_texture =
                            |t: &std::path::PathBuf, key: &str, read: Read| -> Result<u32, SceneError> {
                                if let Some(&k) = images.get(&(t.clone(), read)) {
                                    return Ok(k);
                                }
                                let read_image = match read {
                                    Read::Colour => super::texture::colour_image,
                                    Read::Data => super::texture::data_image,
                                    Read::Coverage => super::texture::coverage_image,
                                };
                                let image = read_image(t).map_err(|e| {
                                    SceneError::new(ctx.path, line, format!("mesh `{file}`: {key}: {e}"))
                                })?;
                                out.textures.push(crate::scene::texture::Texture::image(
                                    image,
                                    Vec2::ONE,
                                    None,
                                    Default::default(),
                                ));
                                out.libraries.push(t.clone());
                                let k = out.textures_before + out.textures.len() as u32 - 1;
                                images.insert((t.clone(), read), k);
                                Ok(k)
                            };
                        let mut maps = crate::scene::Maps::default();
                        if let (Some(t), None) = (&m.texture, m.dielectric) {
                            maps.color = Some(image_texture(t, "map_Kd", Read::Colour)?);
                        }
                        if let Some((t, scale)) = &m.bump {
                            maps.height = Some((image_texture(t, "map_Bump", Read::Data)?, *scale));
                        }
                        if let Some((factor, map)) = &m.alpha {
                            let texture = match map {
                                Some(t) => Some(image_texture(t, "map_d", Read::Coverage)?),
                                None => None,
                            };
                            maps.alpha = Some(crate::scene::cutout::Alpha {
                                mode: crate::scene::cutout::AlphaMode::Blend,
                                factor: *factor,
                                texture,
                            });
                        }
                        if maps != crate::scene::Maps::default() {
                            out.maps.push((id, maps));
                        }
                        id
                    }
                    (None, None) => default_material(materials),
                };
                let part_emission = if c.emission.is_some() {
                    emission
                } else {
                    part.material.as_ref().map_or(Vec3::ZERO, |m| m.emission)
                };
                // (A mesh file's own materials read no solid texture: `solid` is the scene
                // file's material's.)
                let (positions, world) = transform.vertices(&part.positions, solid);
                let normals = part.normals.map(|n| transform.normals(&n));
                let object_name = c.object.clone().unwrap_or_else(|| format!("{name}/{}", part.name));
                let object = out.object(&object_name);
                out.shapes.push(Shape {
                    name: format!("{name}/{}", part.name),
                    geometry: Geometry::Triangles(Mesh {
                        positions,
                        indices: part.indices.into(),
                        normals,
                        uvs: part.uvs.map(Into::into),
                        attributes: None,
                        instance: None,
                        world,
                    }),
                    material: part_material,
                    emission: part_emission,
                    object,
                });
            }
            return Ok(());
        }
        ShapeKind::Gltf(GltfFile { file }) => {
            let line = Some(line_of(ctx.text, span.start));
            let path = dir.join(file);
            let g = crate::scene::limits::check_input_file(&path)
                .and_then(|()| gltf::load(&path))
                .map_err(|e| SceneError::new(ctx.path, line, format!("glTF `{file}`: {e}")))?;
            if material.is_some() || c.emission.is_some() {
                return ctx
                    .err(span, "a glTF shape has its own materials: it takes no `material` or `emission`");
            }
            out.libraries.extend(g.files.iter().cloned());
            out.notes.extend(g.notes.iter().map(|n| format!("glTF `{file}`: {n}")));
            if !g.cameras.is_empty() {
                out.notes.push(format!("glTF `{file}`: its camera is not used (the scene file has one)"));
            }
            let at = gltf::Placement {
                linear: transform.linear,
                translate: transform.translate,
                origin: transform.origin,
            };
            let first_texture = out.textures_before + out.textures.len() as u32;
            let first_material = materials.len() as u32;
            let mut object = |n: &str| out.object(c.object.as_deref().unwrap_or(n));
            let placed = gltf::place(
                &g,
                &name,
                &at,
                first_material,
                first_texture,
                ctx.diffuse_roughness,
                &mut object,
            );
            materials.extend(placed.materials);
            out.material_names.extend(placed.material_names);
            out.textures.extend(placed.textures);
            out.maps.extend(placed.maps);
            let names = &placed.groups.names;
            for &(s, g) in &placed.groups.shapes {
                out.gltf_groups
                    .push((GroupOf::Shape(out.shapes.len() + s as usize), names[g as usize].clone()));
            }
            for &(l, g) in &placed.groups.lights {
                out.gltf_groups
                    .push((GroupOf::Light(out.lights.len() + l as usize), names[g as usize].clone()));
            }
            out.lights.extend(placed.lights);
            out.shapes.extend(placed.shapes);
            return Ok(());
        }
        ShapeKind::Terrain(t) => {
            let resolution = match &t.resolution {
                Some(r) if !(1..=MAX_TERRAIN).contains(r.get_ref()) => {
                    return ctx.err(r.span(), format!("`resolution` must lie between 1 and {MAX_TERRAIN}"))
                }
                Some(r) => *r.get_ref(),
                None => 64,
            };
            let size = t.size.map_or(10.0, |v| v.0);
            if size <= 0.0 {
                return ctx.err(span, "a terrain's `size` must be positive");
            }
            let height = t.height.map_or(1.0, |v| v.0);
            let mut mesh = procedural::terrain(resolution, size, height, t.seed.unwrap_or(0));
            let p: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
            (mesh.positions, mesh.world) = transform.vertices(&p, solid);
            Geometry::Triangles(mesh)
        }
        ShapeKind::Teapot(t) => {
            let resolution = match &t.resolution {
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
            let p: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
            (mesh.positions, mesh.world) = transform.vertices(&p, solid);
            mesh.normals = mesh.normals.map(|n| transform.normals(&n));
            Geometry::Triangles(mesh)
        }
    };
    let material = material.unwrap_or_else(|| default_material(materials));
    let object = out.object(c.object.as_deref().unwrap_or(&name));
    out.shapes.push(Shape { name, geometry, material, emission, object });
    Ok(())
}

fn mesh((positions, world): (Arc<[Vec3A]>, Option<Arc<[DVec3]>>), indices: &[[u32; 3]]) -> Mesh {
    Mesh {
        positions,
        indices: indices.into(),
        normals: None,
        uvs: None,
        attributes: None,
        instance: None,
        world,
    }
}

/// An axis-aligned box as 12 triangles wound counter-clockwise seen from outside.
fn box_mesh(lo: DVec3, hi: DVec3) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let p: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::tests::{error_line, MINIMAL};
    use crate::scene::file::{Exact, Wide};

    #[test]
    fn keys_of_another_type_are_rejected() {
        let text = format!("{MINIMAL}[[shape]]\ntype = \"sphere\"\nradius = 1\nvertices = []\n");
        let (line, msg) = error_line(&text);
        assert_eq!(line, Some(4), "{msg}");
        assert!(msg.contains("vertices"), "{msg}");
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
    fn box_triangles_face_outwards() {
        let (p, tris) = box_mesh(DVec3::splat(-1.0), DVec3::splat(1.0));
        for [a, b, c] in tris {
            let (a, b, c) = (p[a as usize], p[b as usize], p[c as usize]);
            let n = (b - a).cross(c - a);
            let centre = (a + b + c) / 3.0;
            assert!(n.dot(centre) > 0.0, "triangle {a} {b} {c} faces inwards");
        }
    }

    #[test]
    fn transform_applies_scale_rotate_translate() {
        let t = Transform::new(
            Some(&FileTransform {
                scale: Some(F(2.0)),
                rotate: Some(Exact([Wide(0.0), Wide(90.0), Wide(0.0)])),
                translate: Some(Exact([Wide(1.0), Wide(0.0), Wide(0.0)])),
            }),
            DVec3::ZERO,
        );
        let p = t.point(DVec3::X);
        assert!((p - Vec3::new(1.0, 0.0, -2.0)).length() < 1e-5, "{p}");
        // The origin is subtracted in f64, before rounding: one unit at 1e8 survives.
        let far = Transform::new(None, DVec3::splat(1e8));
        assert_eq!(far.point(DVec3::new(1e8 + 1.0, 1e8, 1e8 - 0.5)), Vec3::new(1.0, 0.0, -0.5));
    }
}

/// How a mesh file's material reads an image: as colour (sRGB), as data, or as coverage (its
/// alpha, else its first channel).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Read {
    Colour,
    Data,
    Coverage,
}
