//! PLY meshes, ASCII and binary (either byte order), read by a reader of its own that streams
//! the body into the mesh's arrays. The `vertex` element gives `x`, `y`, `z` (kept in f64, as
//! OBJ's are), and optionally `nx`, `ny`, `nz` and texture coordinates (`u`, `v`, or `s`, `t`,
//! or `texture_u`, `texture_v`). The `face` element's `vertex_indices` (or `vertex_index`)
//! lists polygons, which are fan-triangulated. Other elements and properties (colours,
//! confidence) are read past. A file is one part, named after its stem.
//!
//! The header's counts are checked against the bytes that follow before anything is
//! allocated: a generic reader that builds a map per element turned 15 MB of empty face lists
//! into 3 GB, and an element of no properties declared 10^8 times exhausted memory from a
//! 257-byte file.

use std::path::Path;

use glam::{DVec3, Vec2, Vec3};

use super::obj::ObjPart;
use crate::scene::limits::MAX_ELEMENTS;

/// The longest header read: real ones are a few hundred bytes.
const MAX_HEADER: usize = 1 << 20;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// A scalar type of the format.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

/// A property: a scalar, or a list of scalars preceded by its length.
#[derive(Clone, Debug)]
struct Property {
    name: String,
    /// For a list, the type of its length.
    count: Option<Scalar>,
    value: Scalar,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: u64,
    properties: Vec<Property>,
}

impl Element {
    fn position(&self, names: &[&str]) -> Option<usize> {
        names.iter().find_map(|n| self.properties.iter().position(|p| p.count.is_none() && p.name == *n))
    }

    /// The fewest bytes one element takes in `format`: its scalars, and the length of each
    /// list (an empty list has no values); in ASCII a character and a separator a value.
    fn min_bytes(&self, format: Format) -> u64 {
        self.properties
            .iter()
            .map(|p| match format {
                Format::Ascii => 2,
                _ => p.count.unwrap_or(p.value).size() as u64,
            })
            .sum()
    }
}

/// The header: the format, the elements in order, and where the body starts.
fn header(bytes: &[u8]) -> Result<(Format, Vec<Element>, usize, usize), String> {
    let end = bytes
        .windows(10)
        .take(MAX_HEADER)
        .position(|w| w == b"end_header")
        .ok_or("no `end_header` in its first MiB: not a PLY file")?;
    let mut body = end + 10;
    // The header's last line ends with LF or CR LF.
    if bytes.get(body) == Some(&b'\r') {
        body += 1;
    }
    if bytes.get(body) == Some(&b'\n') {
        body += 1;
    }
    let text = std::str::from_utf8(&bytes[..end]).map_err(|_| "its header is not text")?;
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    if lines.next().map(|(_, l)| l) != Some("ply") {
        return Err("it does not start with `ply`: not a PLY file".into());
    }
    let (mut format, mut elements) = (None, Vec::<Element>::new());
    for (line, l) in lines {
        let words: Vec<&str> = l.split_whitespace().collect();
        let bad = |what: &str| format!("line {line}: {what}");
        match words.as_slice() {
            [] | ["comment", ..] | ["obj_info", ..] => {}
            ["format", f, version] => {
                if *version != "1.0" {
                    return Err(bad(&format!("format version {version}, where 1.0 is read")));
                }
                format = Some(match *f {
                    "ascii" => Format::Ascii,
                    "binary_little_endian" => Format::Little,
                    "binary_big_endian" => Format::Big,
                    _ => return Err(bad(&format!("an unknown format `{f}`"))),
                });
            }
            ["element", name, count] => {
                let count: u64 = count
                    .parse()
                    .map_err(|_| bad(&format!("element `{name}`: a count that is not a whole number")))?;
                elements.push(Element { name: name.to_string(), count, properties: Vec::new() });
            }
            ["property", "list", count, value, name] => {
                let element = elements.last_mut().ok_or_else(|| bad("a property before any element"))?;
                let (Some(count), Some(value)) = (Scalar::parse(count), Scalar::parse(value)) else {
                    return Err(bad("a list of an unknown type"));
                };
                if !count.is_integer() {
                    return Err(bad("a list whose length is not an integer"));
                }
                element.properties.push(Property { name: name.to_string(), count: Some(count), value });
            }
            ["property", ty, name] => {
                let element = elements.last_mut().ok_or_else(|| bad("a property before any element"))?;
                let value = Scalar::parse(ty).ok_or_else(|| bad(&format!("an unknown type `{ty}`")))?;
                element.properties.push(Property { name: name.to_string(), count: None, value });
            }
            _ => return Err(bad(&format!("`{l}` is not a PLY header line"))),
        }
    }
    let format = format.ok_or("no `format` line in its header")?;
    // The body starts on the line after `end_header`.
    let header_lines = text.lines().count() + 2;
    Ok((format, elements, body, header_lines))
}

/// The body, value by value: binary in either byte order, or ASCII tokens with their lines.
struct Body<'a> {
    bytes: &'a [u8],
    at: usize,
    format: Format,
    line: usize,
}

impl Body<'_> {
    /// The next value, as `ty` says, in f64 (exact for every integer type).
    fn value(&mut self, ty: Scalar) -> Result<f64, String> {
        if self.format == Format::Ascii {
            return self.token(ty);
        }
        let n = ty.size();
        let b = self.bytes.get(self.at..self.at + n).ok_or("the file ends early")?;
        self.at += n;
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(b);
        if self.format == Format::Big {
            a[..n].reverse();
        }
        Ok(match ty {
            Scalar::I8 => a[0] as i8 as f64,
            Scalar::U8 => a[0] as f64,
            Scalar::I16 => i16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::U16 => u16::from_le_bytes([a[0], a[1]]) as f64,
            Scalar::I32 => i32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::U32 => u32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F32 => f32::from_le_bytes([a[0], a[1], a[2], a[3]]) as f64,
            Scalar::F64 => f64::from_le_bytes(a),
        })
    }

    fn token(&mut self, ty: Scalar) -> Result<f64, String> {
        while let Some(&c) = self.bytes.get(self.at) {
            if !c.is_ascii_whitespace() {
                break;
            }
            self.line += (c == b'\n') as usize;
            self.at += 1;
        }
        let start = self.at;
        while self.bytes.get(self.at).is_some_and(|c| !c.is_ascii_whitespace()) {
            self.at += 1;
        }
        if start == self.at {
            return Err("the file ends early".into());
        }
        let word = std::str::from_utf8(&self.bytes[start..self.at]).unwrap_or("");
        let bad = || {
            format!(
                "line {}: `{}` is not a {}",
                self.line,
                word.escape_debug(),
                if ty.is_integer() { "whole number" } else { "number" }
            )
        };
        // Each value as its declared type holds it (a `float` rounded to f32, as in a binary
        // file).
        match ty {
            Scalar::F64 => word.parse::<f64>().map_err(|_| bad()),
            Scalar::F32 => word.parse::<f32>().map(f64::from).map_err(|_| bad()),
            _ => word.parse::<i64>().map(|v| v as f64).map_err(|_| bad()),
        }
    }

    /// Where the reader is, for messages: a line of an ASCII file, a byte of a binary one.
    fn place(&self) -> String {
        match self.format {
            Format::Ascii => format!("line {}", self.line),
            _ => format!("byte {}", self.at),
        }
    }
}

/// Loads a PLY file (a regular file of bounded size: the caller checks). Errors name the file
/// and the element, vertex or face at fault. A file without faces gives no part.
pub fn load(path: &Path) -> Result<Vec<ObjPart>, String> {
    let at = |what: String| format!("{}: {what}", path.display());
    let bytes = std::fs::read(path).map_err(|e| at(e.to_string()))?;
    read(&bytes, path).map_err(at)
}

fn read(bytes: &[u8], path: &Path) -> Result<Vec<ObjPart>, String> {
    let (format, elements, start, header_lines) = header(bytes)?;
    let mut left = (bytes.len() - start) as u64;
    for e in &elements {
        if e.properties.is_empty() {
            return Err(format!("element `{}` has no properties", e.name));
        }
        let need = e.count.saturating_mul(e.min_bytes(format));
        if e.count > MAX_ELEMENTS || need > left {
            return Err(format!(
                "element `{}` declares {} elements, which the {left} bytes left in the file cannot hold",
                e.name, e.count
            ));
        }
        left -= need;
    }
    let mut body = Body { bytes, at: start, format, line: header_lines };
    let mut positions: Vec<DVec3> = Vec::new();
    let mut normals: Vec<Vec3> = Vec::new();
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    let mut values = Vec::new();
    let mut list: Vec<i64> = Vec::new();
    for e in &elements {
        let is_vertex = e.name == "vertex";
        let is_face = e.name == "face";
        let [x, y, z, nx, ny, nz] = ["x", "y", "z", "nx", "ny", "nz"].map(|n| e.position(&[n]));
        let (u, v) = (e.position(&["u", "s", "texture_u"]), e.position(&["v", "t", "texture_v"]));
        let indices = ["vertex_indices", "vertex_index"]
            .iter()
            .find_map(|n| e.properties.iter().position(|p| p.count.is_some() && p.name == *n));
        if is_vertex {
            if x.is_none() || y.is_none() || z.is_none() {
                return Err("its vertices have no numeric x, y and z".into());
            }
            positions.reserve(e.count as usize);
        }
        if is_face {
            match indices {
                Some(i) if e.properties[i].value.is_integer() => {}
                _ => return Err("its faces have no integer vertex_indices list".into()),
            }
            triangles.reserve(e.count as usize);
        }
        for k in 0..e.count {
            values.clear();
            for (j, p) in e.properties.iter().enumerate() {
                let Some(count) = p.count else {
                    values.push(body.value(p.value).map_err(|m| format!("{} {k}: {m}", e.name))?);
                    continue;
                };
                values.push(f64::NAN);
                let place = body.place();
                let n = body.value(count).map_err(|m| format!("{} {k}: {m}", e.name))?;
                if !(0.0..=u32::MAX as f64).contains(&n) {
                    return Err(format!("{place}: {} {k}: a list of {n} values", e.name));
                }
                let keep = is_face && Some(j) == indices;
                if keep && n < 3.0 {
                    return Err(format!("{place}: face {k} has {n} vertices; a face needs 3 or more"));
                }
                if format != Format::Ascii
                    && (n as u64) * p.value.size() as u64 > (bytes.len() - body.at) as u64
                {
                    return Err(format!(
                        "{place}: {} {k}: a list of {n} values past the end of the file",
                        e.name
                    ));
                }
                list.clear();
                for _ in 0..n as u64 {
                    let value = body.value(p.value).map_err(|m| format!("{} {k}: {m}", e.name))?;
                    if keep {
                        list.push(value as i64);
                    }
                }
            }
            if is_vertex {
                let get = |i: Option<usize>| i.map(|i| values[i]);
                let (Some(px), Some(py), Some(pz)) = (get(x), get(y), get(z)) else { unreachable!() };
                let p = DVec3::new(px, py, pz);
                if !p.is_finite() || p.abs().max_element() > f32::MAX as f64 {
                    let line =
                        if format == Format::Ascii { format!("{}: ", body.place()) } else { String::new() };
                    return Err(format!(
                        "{line}vertex {k}: a position is not a finite number ({px}, {py}, {pz})"
                    ));
                }
                positions.push(p);
                if let (Some(a), Some(b), Some(c)) = (get(nx), get(ny), get(nz)) {
                    normals.push(DVec3::new(a, b, c).normalize_or_zero().as_vec3());
                }
                if let (Some(a), Some(b)) = (get(u), get(v)) {
                    uvs.push(Vec2::new(a as f32, b as f32));
                }
            }
            if is_face {
                let n = positions.len() as i64;
                if let Some(&bad) = list.iter().find(|&&i| !(0..n).contains(&i)) {
                    return Err(format!("face {k}: vertex index {bad} out of range ({n} vertices)"));
                }
                for t in 1..list.len() - 1 {
                    triangles.push([list[0] as u32, list[t] as u32, list[t + 1] as u32]);
                }
            }
        }
    }
    if triangles.is_empty() {
        return Ok(Vec::new());
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
            ("nan-ascii", nan_ascii(ascii_with(&header("ascii"), "3 0 1 2\n")), "line 16"),
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
