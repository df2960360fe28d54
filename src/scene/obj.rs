//! Wavefront OBJ meshes through `tobj`: polygons triangulated, one part per OBJ object, the
//! `.mtl` Kd as diffuse colour and Ke as emission. When tobj rejects a file, or a vertex is not a
//! finite number, the offending OBJ line is found and named.

use std::cell::RefCell;
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec2, Vec3};

/// What the mesh's `.mtl` says about a part.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjMaterial {
    /// `newmtl`.
    pub name: String,
    /// `Kd`.
    pub diffuse: Vec3,
    /// `Ke`.
    pub emission: Vec3,
    /// `Ks` (zero without).
    pub specular: Vec3,
    /// The GGX roughness of `Ns`, by [`roughness_of_exponent`].
    pub roughness: f32,
    /// `map_Kd`, resolved against the material library's directory.
    pub texture: Option<PathBuf>,
    /// The index of refraction, when the material is a dielectric by [`is_dielectric`].
    pub dielectric: Option<f32>,
    /// `Tf`, the transmission filter of a dielectric (white without).
    pub transmission: Vec3,
    /// `map_Bump` or `bump`: a height image (its luminance) and its `-bm` multiplier, the
    /// height in scene units of a white texel.
    pub bump: Option<(PathBuf, f32)>,
    /// Coverage, when the material is not opaque and not a dielectric: `d` (or 1 - `Tr`) and
    /// `map_d`, multiplying it.
    pub alpha: Option<(f32, Option<PathBuf>)>,
}

/// The file and `-bm` multiplier of a `map_Bump` line's arguments (other options are skipped
/// with their values; the file is the last word).
fn bump_option(args: &str) -> Result<(String, f32), String> {
    let words: Vec<&str> = args.split_whitespace().collect();
    let Some((file, options)) = words.split_last() else { return Err("`map_Bump` names no file".into()) };
    let mut multiplier = 1.0;
    let mut k = 0;
    while k < options.len() {
        if options[k] == "-bm" {
            multiplier = options
                .get(k + 1)
                .and_then(|v| v.parse::<f32>().ok())
                .filter(|v| v.is_finite())
                .ok_or("`map_Bump -bm` takes a finite number")?;
        }
        k += 1;
    }
    Ok((file.to_string(), multiplier))
}

/// The roughness of a Phong exponent `Ns`: the Beckmann width that matches a Phong lobe of
/// exponent n is sqrt(2 / (n + 2)) (Walter et al. 2007, section 5.2), taken as the GGX alpha,
/// and the roughness is its square root (alpha = roughness²). Ns = 0 gives 1 (the roughest),
/// Ns = 10 gives 0.64, Ns = 100 0.37, Ns = 1000 0.21.
pub fn roughness_of_exponent(ns: f32) -> f32 {
    (2.0 / (ns.max(0.0) + 2.0)).sqrt().sqrt().clamp(0.0, 1.0)
}

/// Whether a `.mtl` material is a dielectric (rendered as smooth glass): its illumination model
/// is one of the MTL specification's refracting ones (4, 6, 7, 9), or it is partly transparent
/// (`d` below 1, or `Tr` above 0) with an index of refraction `Ni` above 1. Transparency
/// without refraction is coverage ([`ObjMaterial::alpha`]): a cut-out.
pub fn is_dielectric(illum: Option<u8>, dissolve: f32, ior: Option<f32>) -> bool {
    matches!(illum, Some(4 | 6 | 7 | 9)) || (dissolve < 1.0 && ior.is_some_and(|n| n > 1.0))
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

/// A loaded OBJ: its parts, the material libraries (`mtllib`) it read, and what of them was
/// not read (one note a key a library, naming its first line).
#[derive(Clone, Debug)]
pub struct Obj {
    pub parts: Vec<ObjPart>,
    pub libraries: Vec<PathBuf>,
    pub notes: Vec<String>,
}

/// The `.mtl` keys lightsplit reads.
const READ_KEYS: &[&str] = &[
    "newmtl", "Kd", "Ke", "Ks", "Ns", "Ni", "d", "Tr", "Tf", "illum", "map_Kd", "map_Bump", "map_bump",
    "map_d", "bump",
];

/// One note for each key of a material library that is not read: its first line and how many
/// lines have it.
fn unread_keys(library: &Path) -> Vec<String> {
    let Ok(bytes) = std::fs::read(library) else { return Vec::new() };
    let text = String::from_utf8_lossy(&bytes);
    let mut seen: Vec<(String, usize, usize)> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let Some(key) = line.split_whitespace().next() else { continue };
        if key.starts_with('#') || READ_KEYS.contains(&key) {
            continue;
        }
        match seen.iter_mut().find(|(k, _, _)| k == key) {
            Some(entry) => entry.2 += 1,
            None => seen.push((key.to_string(), n + 1, 1)),
        }
    }
    seen.into_iter()
        .map(|(key, line, count)| {
            let more = if count > 1 { format!(" (on {count} lines)") } else { String::new() };
            format!("{}:{line}: `{key}` is not read{more}", library.display())
        })
        .collect()
}

/// One note for each material a `usemtl` line names that no library defines (the faces after it
/// take the default material): its first line and how many lines name it. A box whose light is
/// such a material renders black, and says why.
fn missing_materials(path: &Path, bytes: &[u8], materials: &[tobj::Material]) -> Vec<String> {
    let text = String::from_utf8_lossy(bytes);
    let mut missing: Vec<(String, usize, usize)> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        if words.next() != Some("usemtl") {
            continue;
        }
        let name = words.collect::<Vec<_>>().join(" ");
        if name.is_empty() || materials.iter().any(|m| m.name == name) {
            continue;
        }
        match missing.iter_mut().find(|(k, _, _)| *k == name) {
            Some(entry) => entry.2 += 1,
            None => missing.push((name, n + 1, 1)),
        }
    }
    missing
        .into_iter()
        .map(|(name, line, count)| {
            let more = if count > 1 { format!(" (on {count} lines)") } else { String::new() };
            let libraries = if materials.is_empty() {
                "no material library defines it"
            } else {
                "its material libraries do not define it"
            };
            format!(
                "{}:{line}: `usemtl {name}`{more}: {libraries}, so its faces take the default material",
                path.display()
            )
        })
        .collect()
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
    let libraries = libraries.into_inner();
    let three = |v: Option<[f64; 3]>| v.map(|v| Vec3::from_array(v.map(|x| x as f32)));
    // A file a library names, relative to that library: the first library's directory where
    // it is found, else the first's (so that a missing file is named there).
    let locate = |t: &str| -> PathBuf {
        let t = t.replace('\\', "/");
        let dirs: Vec<&Path> = libraries.iter().filter_map(|l| l.parent()).collect();
        dirs.iter()
            .map(|d| d.join(&t))
            .find(|p| p.is_file())
            .unwrap_or_else(|| dirs.first().unwrap_or(&dir.as_path()).join(&t))
    };
    let mut read = Vec::new();
    for m in &materials {
        let bad = |what: &str| format!("{}: material `{}`: {what}", path.display(), m.name);
        let number = |key: &str| -> Result<Option<f32>, String> {
            match m.unknown_param.get(key) {
                None => Ok(None),
                Some(v) => v
                    .split_whitespace()
                    .next()
                    .and_then(|x| x.parse::<f32>().ok())
                    .map(Some)
                    .ok_or_else(|| bad(&format!("`{key} {v}` is not a number"))),
            }
        };
        let tf = match m.unknown_param.get("Tf") {
            None => Vec3::ONE,
            Some(v) => {
                let x: Vec<f32> = v.split_whitespace().filter_map(|x| x.parse().ok()).collect();
                match x[..] {
                    [g] => Vec3::splat(g),
                    [r, g, b, ..] => Vec3::new(r, g, b),
                    _ => return Err(bad(&format!("`Tf {v}` is not a colour"))),
                }
            }
        };
        let dissolve = match (m.dissolve, number("Tr")?) {
            (Some(d), _) => d as f32,
            (None, Some(tr)) => 1.0 - tr,
            (None, None) => 1.0,
        };
        let ior = m.optical_density.map(|n| n as f32);
        let material = ObjMaterial {
            name: m.name.clone(),
            diffuse: three(m.diffuse).unwrap_or(Vec3::splat(0.8)),
            emission: three(m.emissive).unwrap_or(Vec3::ZERO),
            specular: three(m.specular).unwrap_or(Vec3::ZERO),
            roughness: roughness_of_exponent(m.shininess.unwrap_or(0.0) as f32),
            texture: m.diffuse_texture.as_ref().map(|t| locate(t)),
            bump: match m.normal_texture.as_deref().map(bump_option) {
                Some(Ok((file, multiplier))) => Some((locate(&file), multiplier)),
                Some(Err(e)) => return Err(bad(&e)),
                None => None,
            },
            dielectric: is_dielectric(m.illumination_model, dissolve, ior)
                .then(|| ior.filter(|&n| n > 1.0).unwrap_or(1.5)),
            transmission: tf,
            alpha: None,
        };
        let mut material = material;
        if material.dielectric.is_none() && (dissolve < 1.0 || m.dissolve_texture.is_some()) {
            material.alpha = Some((dissolve.clamp(0.0, 1.0), m.dissolve_texture.as_ref().map(|t| locate(t))));
        }
        let finite = [material.diffuse, material.emission, material.specular, material.transmission]
            .iter()
            .all(|v| v.is_finite())
            && dissolve.is_finite()
            && m.shininess.is_none_or(f64::is_finite)
            && ior.is_none_or(f32::is_finite);
        if !finite {
            return Err(bad("a Kd, Ke, Ks, Ns, Ni, d, Tr or Tf value is not finite"));
        }
        let unit = |v: Vec3| v.min_element() >= 0.0 && v.max_element() <= 1.0;
        if !(unit(material.diffuse) && unit(material.specular) && unit(material.transmission)) {
            return Err(bad("Kd, Ks and Tf must lie in [0, 1]"));
        }
        if material.emission.min_element() < 0.0
            || material.emission.max_element() > crate::scene::limits::MAX_EMISSION
        {
            return Err(bad("Ke must lie in [0, 1e12]"));
        }
        read.push(material);
    }
    let mut notes: Vec<String> = libraries.iter().flat_map(|l| unread_keys(l)).collect();
    notes.extend(missing_materials(path, &bytes, &materials));
    let materials = read;

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
            material: mesh.material_id.and_then(|i| materials.get(i).cloned()),
        });
    }
    Ok(Obj { parts, libraries, notes })
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
        let m = parts[0].material.as_ref().expect("material");
        assert_eq!(m.diffuse, Vec3::splat(0.5));
        assert_eq!(m.emission, Vec3::new(10.0, 9.0, 8.0));
    }

    /// The `.mtl` keys beyond Kd and Ke: Ks and Ns a glossy lobe, map_Kd a texture beside the
    /// library, d/Tr with Ni or a refracting illum a dielectric, Tf its tint, map_Bump a height
    /// image with its -bm multiplier; every other key one note naming its first line and how
    /// many lines have it.
    #[test]
    fn mtl_materials_and_notes_on_what_is_not_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        std::fs::create_dir(dir.path().join("lib")).expect("mkdir");
        write(
            &dir.path().join("lib"),
            "m.mtl",
            "# materials\nnewmtl shiny\nKa 0.1 0.1 0.1\nKd 0.5 0.4 0.3\nKs 0.2 0.2 0.2\nNs 100\nmap_Kd wood.png\n\
             newmtl glass\nKa 0 0 0\nd 0.2\nNi 1.33\nTf 0.9 1 0.9\nnewmtl cutout\nTr 0.5\nillum 2\n\
             newmtl window\nillum 7\nmap_Bump -bm 0.5 b.png\n",
        );
        let text = "mtllib lib/m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\n";
        let faces =
            ["shiny", "glass", "cutout", "window"].map(|m| format!("o {m}\nusemtl {m}\nf 1 2 3\n")).concat();
        let obj = write(dir.path(), "m.obj", &format!("{text}{faces}"));
        let loaded = load(&obj).expect("loads");
        let m: Vec<&ObjMaterial> =
            loaded.parts.iter().map(|p| p.material.as_ref().expect("material")).collect();
        assert_eq!(m[0].specular, Vec3::splat(0.2));
        assert!((m[0].roughness - (2.0f32 / 102.0).sqrt().sqrt()).abs() < 1e-6, "{}", m[0].roughness);
        assert_eq!(m[0].texture, Some(dir.path().join("lib").join("wood.png")));
        assert_eq!(
            (m[0].dielectric, m[1].dielectric, m[2].dielectric, m[3].dielectric),
            (None, Some(1.33), None, Some(1.5))
        );
        assert_eq!(m[1].transmission, Vec3::new(0.9, 1.0, 0.9));
        let lib = dir.path().join("lib").join("m.mtl");
        assert_eq!(loaded.notes, [format!("{}:3: `Ka` is not read (on 2 lines)", lib.display())]);
        assert_eq!(m[3].bump, Some((dir.path().join("lib").join("b.png"), 0.5)));
        assert_eq!(roughness_of_exponent(0.0), 1.0);
        assert!(roughness_of_exponent(1e6) < 0.05);
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
