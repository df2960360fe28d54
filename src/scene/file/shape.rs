//! `[[shape]]`: spheres, quads, boxes, OBJ/PLY meshes and the procedural terrain and teapot, each
//! under an optional transform (scale, rotate, translate), with its material, emission and the
//! object it belongs to.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use glam::{Mat3, Vec2, Vec3, Vec3A};
use serde::Deserialize;
use toml::Spanned;

use super::typed::{Table, Typed};
use super::{line_of, v3, Ctx, F, V3};
use crate::scene::{obj, procedural, teapot, Geometry, Material, Mesh, SceneError, Shape};

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
    Terrain(Terrain),
    Teapot(Teapot),
}

impl Typed for ShapeKind {
    type Common = ShapeCommon;
    const SECTION: &'static str = "shape";
}

/// Mesh formats that are not Wavefront OBJ, named in the error rather than read as an empty OBJ.
const OTHER_MESH_FORMATS: &[&str] =
    &["ply", "gltf", "glb", "fbx", "stl", "dae", "3ds", "usd", "usda", "usdc", "usdz", "abc", "blend"];

impl ShapeKind {
    /// The file a mesh reads, as written (relative to the scene file).
    pub(super) fn file(&self) -> Option<&str> {
        match self {
            ShapeKind::Mesh(MeshFile { file }) => Some(file),
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

/// The shapes built so far and the objects they belong to.
#[derive(Default)]
pub(super) struct Builder {
    pub shapes: Vec<Shape>,
    pub objects: Vec<String>,
    object_ids: HashMap<String, u32>,
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
    let transform = Transform::new(c.transform.as_ref());
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
    let default_material = |materials: &mut Vec<Material>| -> u32 {
        materials.push(Material::Diffuse { albedo: Vec3::splat(0.8) });
        (materials.len() - 1) as u32
    };

    let geometry = match &s.of_type {
        ShapeKind::Sphere(sphere) => {
            if transform.rotates {
                return ctx.err(span, "a sphere takes no `rotate`");
            }
            let radius = sphere.radius.0 * transform.scale;
            if radius < 0.0 {
                return ctx.err(span, "a sphere's `radius` must not be negative");
            }
            let center = transform.point(sphere.center.map(v3).unwrap_or(Vec3::ZERO));
            Geometry::Sphere { center, radius }
        }
        ShapeKind::Quad(Quad { vertices: v }) => {
            if v.len() != 4 {
                return ctx.err(span, format!("a quad needs 4 `vertices`, not {}", v.len()));
            }
            let p: Vec<Vec3> = v.iter().map(|&p| transform.point(v3(p))).collect();
            let mut quad = mesh(&p, &[[0, 1, 2], [0, 2, 3]]);
            // An image's bottom left, bottom right, top right and top left.
            quad.uvs = Some([Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y].into());
            Geometry::Triangles(quad)
        }
        ShapeKind::Box(b) => {
            let (lo, hi) = (v3(b.min), v3(b.max));
            if lo.cmpge(hi).any() {
                return ctx.err(span, "a box's `min` must be below its `max` on every axis");
            }
            let (p, i) = box_mesh(lo, hi);
            let p: Vec<Vec3> = p.iter().map(|&q| transform.point(q)).collect();
            Geometry::Triangles(mesh(&p, &i))
        }
        ShapeKind::Mesh(MeshFile { file }) => {
            let line = Some(line_of(ctx.text, span.start));
            let path = dir.join(file);
            // Formats an OBJ reader would read as an OBJ without faces.
            let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
            if let Some(ext) = ext.filter(|e| OTHER_MESH_FORMATS.contains(&e.as_str())) {
                return ctx.err(
                    span,
                    format!(
                        "mesh `{file}`: .{ext} is not read; meshes are Wavefront OBJ files (.obj, with .mtl)"
                    ),
                );
            }
            let parts = crate::scene::limits::check_input_file(&path)
                .and_then(|()| obj::load(&path))
                .map_err(|e| SceneError::new(ctx.path, line, format!("mesh `{file}`: {e}")))?;
            if parts.is_empty() {
                return ctx.err(span, format!("mesh `{file}` has no faces (meshes are Wavefront OBJ files)"));
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
                let part_emission = if c.emission.is_some() {
                    emission
                } else {
                    part.material.map_or(Vec3::ZERO, |m| m.emission)
                };
                let positions: Vec<Vec3> = part.positions.iter().map(|&p| transform.point(p)).collect();
                let normals = part.normals.map(|n| transform.normals(&n));
                let object_name = c.object.clone().unwrap_or_else(|| format!("{name}/{}", part.name));
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
            if transform.rotates || transform.scale != 1.0 || transform.translate != Vec3::ZERO {
                mesh.positions =
                    mesh.positions.iter().map(|&p| Vec3A::from(transform.point(p.into()))).collect();
            }
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
            mesh.positions = mesh.positions.iter().map(|&p| Vec3A::from(transform.point(p.into()))).collect();
            mesh.normals = mesh.normals.map(|n| transform.normals(&n));
            Geometry::Triangles(mesh)
        }
    };
    let material = material.unwrap_or_else(|| default_material(materials));
    let object = out.object(c.object.as_deref().unwrap_or(&name));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::tests::{error_line, MINIMAL};
    use crate::scene::file::Exact;

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
            rotate: Some(Exact([F(0.0), F(90.0), F(0.0)])),
            translate: Some(Exact([F(1.0), F(0.0), F(0.0)])),
        }));
        let p = t.point(Vec3::X);
        assert!((p - Vec3::new(1.0, 0.0, -2.0)).length() < 1e-5, "{p}");
    }
}
