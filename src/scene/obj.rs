//! Wavefront OBJ meshes through `tobj`: polygons triangulated, one part per OBJ object, the
//! `.mtl` Kd as diffuse colour and Ke as emission. When tobj rejects a file, or a vertex is not a
//! finite number, the offending OBJ line is found and named.

use std::path::Path;

use glam::{Vec2, Vec3};

/// What the mesh's `.mtl` says about a part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjMaterial {
    pub diffuse: Vec3,
    pub emission: Vec3,
}

/// One OBJ object, re-indexed on its own vertices.
#[derive(Clone, Debug)]
pub struct ObjPart {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    /// Texture coordinates, one per vertex, when the file has them (`vt`).
    pub uvs: Option<Vec<Vec2>>,
    pub indices: Vec<[u32; 3]>,
    pub material: Option<ObjMaterial>,
}

fn triple(values: &[f32]) -> Vec3 {
    match values {
        [a, b, c, ..] => Vec3::new(*a, *b, *c),
        _ => Vec3::ZERO,
    }
}

/// Loads an OBJ file. Errors are messages naming the OBJ file and, where found, its line.
pub fn load(path: &Path) -> Result<Vec<ObjPart>, String> {
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let (models, materials) = match tobj::load_obj(path, &options) {
        Ok(loaded) => loaded,
        Err(e) => return Err(describe(path, &e.to_string())),
    };
    let materials = materials.map_err(|e| format!("{}: material library: {e}", path.display()))?;
    let materials: Vec<ObjMaterial> = materials
        .iter()
        .map(|m| ObjMaterial {
            diffuse: m.diffuse.map_or(Vec3::splat(0.8), Vec3::from_array),
            emission: m.emissive.map_or(Vec3::ZERO, Vec3::from_array),
        })
        .collect();
    for m in &materials {
        if !(m.diffuse.is_finite() && m.emission.is_finite()) {
            return Err(format!("{}: material library: a Kd or Ke value is not finite", path.display()));
        }
        if m.diffuse.min_element() < 0.0
            || m.diffuse.max_element() > 1.0
            || m.emission.min_element() < 0.0
            || m.emission.max_element() > crate::scene::limits::MAX_EMISSION
        {
            return Err(format!(
                "{}: material library: Kd must lie in [0, 1] and Ke in [0, 1e12]",
                path.display()
            ));
        }
    }

    let mut parts = Vec::new();
    for model in models {
        let mesh = &model.mesh;
        if mesh.indices.is_empty() {
            continue;
        }
        let positions: Vec<Vec3> = mesh.positions.chunks_exact(3).map(triple).collect();
        if positions.iter().any(|p| !p.is_finite()) {
            return Err(describe(path, "a vertex position is not a finite number"));
        }
        let normals = (mesh.normals.len() == mesh.positions.len())
            .then(|| mesh.normals.chunks_exact(3).map(|n| triple(n).normalize_or_zero()).collect::<Vec<_>>());
        let uvs = (mesh.texcoords.len() / 2 == positions.len() && !mesh.texcoords.is_empty())
            .then(|| mesh.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])).collect::<Vec<_>>())
            .filter(|uvs| uvs.iter().all(|t| t.is_finite()));
        let indices: Vec<[u32; 3]> = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        if indices.iter().flatten().any(|&i| i as usize >= positions.len()) {
            return Err(describe(path, "face vertex index out of bounds"));
        }
        parts.push(ObjPart {
            name: model.name.clone(),
            positions,
            normals,
            uvs,
            indices,
            material: mesh.material_id.and_then(|i| materials.get(i).copied()),
        });
    }
    Ok(parts)
}

/// Names the OBJ line that explains `message`, when one can be found: a vertex that is not a
/// finite number, or a face index outside the vertices defined so far.
fn describe(path: &Path, message: &str) -> String {
    let Ok(text) = std::fs::read_to_string(path) else {
        return format!("{}: {message}", path.display());
    };
    let mut vertices: i64 = 0;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                vertices += 1;
                if words.take(3).any(|w| w.parse::<f32>().map_or(true, |x| !x.is_finite())) {
                    return format!("{}:{}: {message} (vertex {vertices})", path.display(), n + 1);
                }
            }
            Some("f") => {
                for w in words {
                    let index = w.split('/').next().and_then(|i| i.parse::<i64>().ok());
                    let resolved = index.map(|i| if i < 0 { vertices + i } else { i - 1 });
                    if !matches!(resolved, Some(r) if (0..vertices).contains(&r)) {
                        return format!(
                            "{}:{}: {message} (`{w}` with {vertices} vertices defined)",
                            path.display(),
                            n + 1
                        );
                    }
                }
            }
            _ => {}
        }
    }
    format!("{}: {message}", path.display())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).expect("write");
        p
    }

    #[test]
    fn quads_are_triangulated_with_mtl_colours() {
        let dir = tempfile::tempdir().expect("tempdir");
        write(dir.path(), "m.mtl", "newmtl lamp\nKd 0.5 0.5 0.5\nKe 10 9 8\n");
        let obj = write(
            dir.path(),
            "m.obj",
            "mtllib m.mtl\no lamp\nusemtl lamp\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n",
        );
        let parts = load(&obj).expect("loads");
        assert_eq!(parts.len(), 1);
        assert_eq!(parts[0].indices.len(), 2);
        let m = parts[0].material.expect("material");
        assert_eq!(m.diffuse, Vec3::splat(0.5));
        assert_eq!(m.emission, Vec3::new(10.0, 9.0, 8.0));
    }

    #[test]
    fn bad_index_names_the_obj_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let obj = write(dir.path(), "bad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 9\n");
        let e = load(&obj).expect_err("index 9 is out of range");
        assert!(e.contains("bad.obj:5:"), "{e}");
    }

    #[test]
    fn nan_vertex_names_the_obj_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let obj = write(dir.path(), "nan.obj", "v 0 0 0\nv nan 0 0\nv 1 1 0\nf 1 2 3\n");
        let e = load(&obj).expect_err("nan vertex");
        assert!(e.contains("nan.obj:2:"), "{e}");
    }
}
