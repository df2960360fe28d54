//! Wavefront OBJ meshes through `tobj`: polygons triangulated, one part per OBJ object, the
//! `.mtl` Kd as diffuse colour and Ke as emission. When tobj rejects a file, or a vertex is not a
//! finite number, the offending OBJ line is found and named.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec2, Vec3};

/// What the mesh's `.mtl` says about a part.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObjMaterial {
    pub diffuse: Vec3,
    pub emission: Vec3,
}

/// One OBJ object, re-indexed on its own vertices. Positions stay in f64, as written, until
/// the scene subtracts its origin (far from the origin f32 cannot hold them).
#[derive(Clone, Debug)]
pub struct ObjPart {
    pub name: String,
    pub positions: Vec<DVec3>,
    pub normals: Option<Vec<Vec3>>,
    /// Texture coordinates, one per vertex, when the file has them (`vt`).
    pub uvs: Option<Vec<Vec2>>,
    pub indices: Vec<[u32; 3]>,
    pub material: Option<ObjMaterial>,
}

/// A loaded OBJ: its parts, and the material libraries (`mtllib`) it read.
#[derive(Clone, Debug)]
pub struct Obj {
    pub parts: Vec<ObjPart>,
    pub libraries: Vec<PathBuf>,
}

fn triple(values: &[f64]) -> DVec3 {
    match values {
        [a, b, c, ..] => DVec3::new(*a, *b, *c),
        _ => DVec3::ZERO,
    }
}

/// Loads an OBJ file (a regular file of bounded size: the caller checks). Errors are messages
/// naming the OBJ file and, where found, its line.
pub fn load(path: &Path) -> Result<Obj, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let options = tobj::LoadOptions { triangulate: true, single_index: true, ..Default::default() };
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    // Each library read, and why one could not be (a library is an input like any other).
    let libraries = RefCell::new(Vec::new());
    let library_error = RefCell::new(None);
    let loaded = tobj::load_obj_buf(&mut std::io::Cursor::new(&bytes), &options, |name| {
        let full = dir.join(name);
        libraries.borrow_mut().push(full.clone());
        match crate::scene::limits::check_input_file(&full) {
            Ok(()) => tobj::load_mtl(&full),
            Err(e) => {
                library_error.borrow_mut().get_or_insert(e);
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    });
    let (models, materials) = match loaded {
        Ok(loaded) => loaded,
        Err(e) => return Err(describe(path, &bytes, &e.to_string())),
    };
    let materials = materials.map_err(|e| match library_error.borrow_mut().take() {
        Some(why) => format!("{}: material library: {why}", path.display()),
        None => format!("{}: material library: {e}", path.display()),
    })?;
    let materials: Vec<ObjMaterial> = materials
        .iter()
        .map(|m| ObjMaterial {
            diffuse: m.diffuse.map_or(Vec3::splat(0.8), |d| Vec3::from_array(d.map(|x| x as f32))),
            emission: m.emissive.map_or(Vec3::ZERO, |e| Vec3::from_array(e.map(|x| x as f32))),
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
        let positions: Vec<DVec3> = mesh.positions.chunks_exact(3).map(triple).collect();
        if positions.iter().any(|p| !p.is_finite() || p.abs().max_element() > f32::MAX as f64) {
            return Err(describe(path, &bytes, "a vertex position is not a finite number"));
        }
        let normals = (mesh.normals.len() == mesh.positions.len()).then(|| {
            mesh.normals.chunks_exact(3).map(|n| triple(n).normalize_or_zero().as_vec3()).collect::<Vec<_>>()
        });
        let uvs = (mesh.texcoords.len() / 2 == positions.len() && !mesh.texcoords.is_empty())
            .then(|| {
                mesh.texcoords
                    .chunks_exact(2)
                    .map(|t| Vec2::new(t[0] as f32, t[1] as f32))
                    .collect::<Vec<_>>()
            })
            .filter(|uvs| uvs.iter().all(|t| t.is_finite()));
        let indices: Vec<[u32; 3]> = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        if indices.iter().flatten().any(|&i| i as usize >= positions.len()) {
            return Err(describe(path, &bytes, "face vertex index out of bounds"));
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
    Ok(Obj { parts, libraries: libraries.into_inner() })
}

/// Names the OBJ line that explains `message`, when one can be found: a `v`, `vt` or `vn` line
/// without its finite numbers, or a face index outside the vertices, texture coordinates or
/// normals defined so far.
fn describe(path: &Path, bytes: &[u8], message: &str) -> String {
    let text = String::from_utf8_lossy(bytes);
    // Defined so far: positions, texture coordinates, normals.
    let mut defined = [0i64; 3];
    const WHAT: [&str; 3] = ["vertices", "texture coordinates", "normals"];
    const ONE: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    let at = |n: usize, detail: String| format!("{}:{}: {message} ({detail})", path.display(), n + 1);
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let (kind, count) = match words.next() {
            Some("v") => (0, 3),
            Some("vt") => (1, 2),
            Some("vn") => (2, 3),
            Some("f") => {
                for w in words {
                    for (i, index) in w.split('/').enumerate().take(3) {
                        // `1//3`: no texture coordinate.
                        if i > 0 && index.is_empty() {
                            continue;
                        }
                        let resolved =
                            index.parse::<i64>().ok().map(|k| if k < 0 { defined[i] + k } else { k - 1 });
                        if !matches!(resolved, Some(r) if (0..defined[i]).contains(&r)) {
                            let which = ONE[i];
                            return at(
                                n,
                                format!("{which} `{index}` of `{w}` with {} {} defined", defined[i], WHAT[i]),
                            );
                        }
                    }
                }
                continue;
            }
            _ => continue,
        };
        defined[kind] += 1;
        let numbers: Vec<Option<f64>> =
            words.take(count).map(|w| w.parse::<f64>().ok().filter(|x| x.is_finite())).collect();
        if numbers.len() < count || numbers.iter().any(Option::is_none) {
            let name = ONE[kind];
            return at(n, format!("{name} {} needs {count} finite numbers", defined[kind]));
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
        let loaded = load(&obj).expect("loads");
        assert_eq!(loaded.libraries, [dir.path().join("m.mtl")]);
        let parts = loaded.parts;
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

    /// A short `v`, `vt` or `vn` line and a face's texture or normal index out of range are
    /// named by their line (they were not).
    #[test]
    fn short_lines_and_bad_uv_and_normal_indices_name_the_obj_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let cases = [
            ("short-v", "v 0 0 0\nv 1 0\nv 1 1 0\nf 1 2 3\n", 2, "vertex 2 needs 3"),
            (
                "short-vt",
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0\nf 1/1 2/1 3/1\n",
                4,
                "texture coordinate 1 needs 2",
            ),
            ("short-vn", "v 0 0 0\nv 1 0 0\nv 1 1 0\nvn 0 1\nf 1//1 2//1 3//1\n", 4, "normal 1 needs 3"),
            (
                "uv-range",
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nf 1/1 2/1 3/7\n",
                5,
                "texture coordinate `7` of `3/7` with 1 texture coordinates defined",
            ),
            (
                "normal-range",
                "v 0 0 0\nv 1 0 0\nv 1 1 0\nvn 0 0 1\nf 1//1 2//1 3//-4\n",
                5,
                "normal `-4` of `3//-4` with 1 normals defined",
            ),
        ];
        for (name, text, line, detail) in cases {
            let obj = write(dir.path(), &format!("{name}.obj"), text);
            let e = load(&obj).expect_err(name);
            assert!(e.contains(&format!("{name}.obj:{line}:")) && e.contains(detail), "{name}: {e}");
        }
    }

    /// Coordinates are read in f64: one unit at 1e8 survives (f32's step there is 8).
    #[test]
    fn coordinates_keep_f64_precision() {
        let dir = tempfile::tempdir().expect("tempdir");
        let obj =
            write(dir.path(), "far.obj", "v 100000001 0 0\nv 100000000 1 0\nv 100000000 0 1\nf 1 2 3\n");
        let parts = load(&obj).expect("loads").parts;
        assert_eq!(parts[0].positions[0].x - parts[0].positions[1].x, 1.0);
    }
}
