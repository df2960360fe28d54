//! PLY meshes, ASCII and binary, through `ply-rs-bw`. The `vertex` element gives `x`, `y`, `z`
//! (kept in f64, as OBJ's are), and optionally `nx`, `ny`, `nz` and texture coordinates (`u`,
//! `v`, or `s`, `t`, or `texture_u`, `texture_v`). The `face` element's `vertex_indices` (or
//! `vertex_index`) lists polygons, which are fan-triangulated. Other elements and properties
//! (colours, confidence) are not read. A file is one part, named after its stem.

use std::path::Path;

use glam::{DVec3, Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use super::obj::ObjPart;

/// A scalar property as f64; `None` for a list.
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v as f64,
        Property::UChar(v) => v as f64,
        Property::Short(v) => v as f64,
        Property::UShort(v) => v as f64,
        Property::Int(v) => v as f64,
        Property::UInt(v) => v as f64,
        Property::Float(v) => v as f64,
        Property::Double(v) => v,
        _ => return None,
    })
}

/// An integer list property (a face's vertex indices); `None` for a scalar or a float list.
fn indices(p: &Property) -> Option<Vec<i64>> {
    Some(match p {
        Property::ListChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUChar(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUShort(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListInt(v) => v.iter().map(|&i| i as i64).collect(),
        Property::ListUInt(v) => v.iter().map(|&i| i as i64).collect(),
        _ => return None,
    })
}

/// Loads a PLY file (a regular file of bounded size: the caller checks). Errors name the file
/// and the vertex or face at fault. A file without faces gives no part.
pub fn load(path: &Path) -> Result<Vec<ObjPart>, String> {
    let at = |what: String| format!("{}: {what}", path.display());
    let mut file = std::fs::File::open(path).map_err(|e| at(e.to_string()))?;
    let ply = Parser::<DefaultElement>::new().read_ply(&mut file).map_err(|e| at(e.to_string()))?;
    let empty = Vec::new();
    let vertices = ply.payload.get("vertex").unwrap_or(&empty);
    let faces = ply.payload.get("face").unwrap_or(&empty);
    if faces.is_empty() {
        return Ok(Vec::new());
    }
    let read = |v: &DefaultElement, keys: &[&str]| keys.iter().find_map(|k| v.get(*k).and_then(scalar));
    let mut positions = Vec::with_capacity(vertices.len());
    let mut normals = Vec::with_capacity(vertices.len());
    let mut uvs = Vec::with_capacity(vertices.len());
    for (i, v) in vertices.iter().enumerate() {
        let [x, y, z] = ["x", "y", "z"].map(|k| read(v, &[k]));
        let (Some(x), Some(y), Some(z)) = (x, y, z) else {
            return Err(at(format!("vertex {i} has no numeric x, y and z")));
        };
        let p = DVec3::new(x, y, z);
        if !p.is_finite() || p.abs().max_element() > f32::MAX as f64 {
            return Err(at(format!("vertex {i}: a position is not a finite number ({x}, {y}, {z})")));
        }
        positions.push(p);
        if let (Some(nx), Some(ny), Some(nz)) = (read(v, &["nx"]), read(v, &["ny"]), read(v, &["nz"])) {
            normals.push(DVec3::new(nx, ny, nz).normalize_or_zero().as_vec3());
        }
        let u = read(v, &["u", "s", "texture_u"]);
        let w = read(v, &["v", "t", "texture_v"]);
        if let (Some(u), Some(w)) = (u, w) {
            uvs.push(Vec2::new(u as f32, w as f32));
        }
    }
    let n = positions.len() as i64;
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(faces.len());
    for (f, face) in faces.iter().enumerate() {
        let list = ["vertex_indices", "vertex_index"].iter().find_map(|k| face.get(*k).and_then(indices));
        let Some(list) = list else {
            return Err(at(format!("face {f} has no integer vertex_indices list")));
        };
        if list.len() < 3 {
            return Err(at(format!("face {f} has {} vertices; a face needs 3 or more", list.len())));
        }
        if let Some(&bad) = list.iter().find(|&&i| !(0..n).contains(&i)) {
            return Err(at(format!("face {f}: vertex index {bad} out of range ({n} vertices)")));
        }
        for k in 1..list.len() - 1 {
            triangles.push([list[0] as u32, list[k] as u32, list[k + 1] as u32]);
        }
    }
    let complete = |len: usize| len == positions.len();
    Ok(vec![ObjPart {
        name: path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
        normals: complete(normals.len())
            .then_some(normals)
            .filter(|n: &Vec<Vec3>| n.iter().all(|v| v.is_finite())),
        uvs: complete(uvs.len()).then_some(uvs).filter(|t: &Vec<Vec2>| t.iter().all(|v| v.is_finite())),
        positions,
        indices: triangles,
        material: None,
    }])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same quad with normals and uvs, as ASCII and as binary little-endian: both read
    /// equal, the quad fan-triangulated.
    #[test]
    fn ascii_and_binary_read_the_same_mesh() {
        let dir = tempfile::tempdir().expect("tempdir");
        let header = |format: &str| {
            format!(
                "ply\nformat {format} 1.0\ncomment made by a test\nelement vertex 4\nproperty double x\nproperty double y\n\
                 property double z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty float u\n\
                 property float v\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n"
            )
        };
        let corners = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [100000000.5, 1.0, 0.0]];
        let mut ascii = header("ascii");
        let mut binary = header("binary_little_endian").into_bytes();
        for (i, c) in corners.iter().enumerate() {
            let uv = [(i % 2) as f32, (i / 2) as f32];
            ascii.push_str(&format!("{} {} {} 0 0 1 {} {}\n", c[0], c[1], c[2], uv[0], uv[1]));
            c.iter().for_each(|x: &f64| binary.extend(x.to_le_bytes()));
            [0.0f32, 0.0, 1.0, uv[0], uv[1]].iter().for_each(|x| binary.extend(x.to_le_bytes()));
        }
        ascii.push_str("4 0 1 2 3\n");
        binary.push(4);
        [0i32, 1, 2, 3].iter().for_each(|i| binary.extend(i.to_le_bytes()));
        std::fs::write(dir.path().join("a.ply"), ascii).expect("write");
        std::fs::write(dir.path().join("b.ply"), &binary).expect("write");
        let a = load(&dir.path().join("a.ply")).expect("ascii");
        let b = load(&dir.path().join("b.ply")).expect("binary");
        assert_eq!(a[0].indices, [[0, 1, 2], [0, 2, 3]]);
        assert_eq!(a[0].positions[3].x, 100000000.5, "f64 kept");
        let (p, q) = (&a[0], &b[0]);
        assert_eq!(
            (&p.positions, &p.indices, &p.normals, &p.uvs),
            (&q.positions, &q.indices, &q.normals, &q.uvs)
        );
        assert_eq!(a[0].normals.as_ref().map(|n| n[0]), Some(Vec3::Z));
        assert_eq!(a[0].uvs.as_ref().map(|t| t[3]), Some(Vec2::new(1.0, 1.0)));
        // Bad files: each one error naming the file, never a panic.
        let bad = [
            ("truncated", binary[..binary.len() - 3].to_vec(), ""),
            ("index", ascii_with(&header("ascii"), "3 0 1 7\n"), "vertex index 7 out of range"),
            (
                "nan",
                nan_first(&binary, header("binary_little_endian").len()),
                "vertex 0: a position is not a finite",
            ),
            ("nan-ascii", nan_ascii(ascii_with(&header("ascii"), "3 0 1 2\n")), "Line 16"),
            ("two", ascii_with(&header("ascii"), "2 0 1\n"), "a face needs 3"),
            ("header", b"ply\nformat ascii 1.0\nelement vertex 1\n".to_vec(), ""),
        ];
        for (name, bytes, want) in bad {
            let path = dir.path().join(format!("{name}.ply"));
            std::fs::write(&path, bytes).expect("write");
            let e = load(&path).expect_err(name);
            assert!(e.contains(&format!("{name}.ply")) && e.contains(want), "{name}: {e}");
        }
    }

    /// The binary body's first coordinate (a double after `header` bytes) made NaN.
    fn nan_first(binary: &[u8], header: usize) -> Vec<u8> {
        let mut bytes = binary.to_vec();
        bytes[header..header + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        bytes
    }

    /// The ASCII body's first vertex made `nan` (which the parser refuses, naming the line).
    fn nan_ascii(bytes: Vec<u8>) -> Vec<u8> {
        String::from_utf8_lossy(&bytes).replacen("end_header\n0 ", "end_header\nnan ", 1).into_bytes()
    }

    /// Four unit vertices and one face line: an ASCII body under `header`.
    fn ascii_with(header: &str, face: &str) -> Vec<u8> {
        let mut text = header.to_string();
        for _ in 0..4 {
            text.push_str("0 0 0 0 0 1 0 0\n");
        }
        text.push_str(face);
        text.into_bytes()
    }
}
