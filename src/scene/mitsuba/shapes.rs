//! The geometry of Mitsuba's shape plugins, in the shape's own coordinates before its
//! `to_world`: the analytic shapes as Mitsuba defines them (`rectangle` the square [-1, 1]² at
//! z = 0 facing +z, `cube` [-1, 1]³, `disk` the unit disc facing +z, `cylinder` of radius 1
//! from z = 0 to z = 1 without caps), tessellated finely enough that their areas are within
//! 1e-4 of the true ones; and Mitsuba's `serialized` meshes (zlib-compressed, version 3 or 4).
//!
//! Texture coordinates are Mitsuba's (v = 0 at an image's top row) turned to lightsplit's
//! (v = 0 at its bottom row): v is 1 - v.

use std::f64::consts::TAU;
use std::io::Read;
use std::path::Path;

use glam::{DVec2, DVec3};

/// A triangle mesh in f64, before placement.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RawMesh {
    pub positions: Vec<DVec3>,
    pub normals: Option<Vec<DVec3>>,
    pub uvs: Option<Vec<DVec2>>,
    pub indices: Vec<[u32; 3]>,
}

impl RawMesh {
    /// Angle-weighted vertex normals (Mitsuba's `recompute_vertex_normals`), for a mesh read
    /// without normals that is not to be shaded flat.
    pub fn smooth_normals(&mut self) {
        let mut normals = vec![DVec3::ZERO; self.positions.len()];
        for t in &self.indices {
            let p = t.map(|i| self.positions.get(i as usize).copied().unwrap_or_default());
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            for k in 0..3 {
                let (a, b) = (
                    (p[(k + 1) % 3] - p[k]).normalize_or_zero(),
                    (p[(k + 2) % 3] - p[k]).normalize_or_zero(),
                );
                let angle = a.dot(b).clamp(-1.0, 1.0).acos();
                if let Some(v) = normals.get_mut(t[k] as usize) {
                    *v += n * angle;
                }
            }
        }
        self.normals = Some(normals.into_iter().map(|n| n.normalize_or_zero()).collect());
    }

    /// Turns the mesh inside out: winding and normals (Mitsuba's `flip_normals`).
    pub fn flip(&mut self) {
        self.indices.iter_mut().for_each(|t| t.swap(1, 2));
        if let Some(ns) = &mut self.normals {
            ns.iter_mut().for_each(|n| *n = -*n);
        }
    }
}

/// Mitsuba's uv (v down) as lightsplit's (v up).
fn uv(u: f64, v: f64) -> DVec2 {
    DVec2::new(u, 1.0 - v)
}

/// The square [-1, 1]² at z = 0, facing +z.
pub fn rectangle() -> RawMesh {
    let p = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
    RawMesh {
        positions: p.iter().map(|&(x, y)| DVec3::new(x, y, 0.0)).collect(),
        normals: Some(vec![DVec3::Z; 4]),
        uvs: Some(p.iter().map(|&(x, y)| uv(0.5 * (x + 1.0), 0.5 * (y + 1.0))).collect()),
        indices: vec![[0, 1, 2], [0, 2, 3]],
    }
}

/// The cube [-1, 1]³, its faces outward, each with its own vertices.
pub fn cube() -> RawMesh {
    let mut m = RawMesh { normals: Some(Vec::new()), uvs: Some(Vec::new()), ..Default::default() };
    for axis in 0..3 {
        for sign in [-1.0, 1.0] {
            let mut n = DVec3::ZERO;
            n[axis] = sign;
            // Two tangents with s x t = n.
            let (mut s, mut t) = (DVec3::ZERO, DVec3::ZERO);
            s[(axis + 1) % 3] = 1.0;
            t[(axis + 2) % 3] = 1.0;
            if sign < 0.0 {
                std::mem::swap(&mut s, &mut t);
            }
            let base = m.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                m.positions.push(n + s * a + t * b);
                if let (Some(ns), Some(uvs)) = (&mut m.normals, &mut m.uvs) {
                    ns.push(n);
                    uvs.push(uv(0.5 * (a + 1.0), 0.5 * (b + 1.0)));
                }
            }
            m.indices.push([base, base + 1, base + 2]);
            m.indices.push([base, base + 2, base + 3]);
        }
    }
    m
}

/// Segments around a disc or a cylinder: the polygon's area is within 1e-4 of the circle's.
const SEGMENTS: u32 = 256;

/// The unit disc at z = 0, facing +z: a fan.
pub fn disk() -> RawMesh {
    let mut m = RawMesh {
        positions: vec![DVec3::ZERO],
        normals: Some(vec![DVec3::Z]),
        uvs: Some(vec![uv(0.0, 0.0)]),
        indices: Vec::new(),
    };
    // The polygon inscribed in a circle slightly wider, so that its area is the disc's.
    let k = SEGMENTS as f64;
    let r = (std::f64::consts::PI / (0.5 * k * (TAU / k).sin())).sqrt();
    for i in 0..SEGMENTS {
        let phi = TAU * i as f64 / k;
        m.positions.push(DVec3::new(r * phi.cos(), r * phi.sin(), 0.0));
        if let (Some(ns), Some(uvs)) = (&mut m.normals, &mut m.uvs) {
            ns.push(DVec3::Z);
            uvs.push(uv(1.0, i as f64 / k));
        }
        m.indices.push([0, 1 + i, 1 + (i + 1) % SEGMENTS]);
    }
    m
}

/// The cylinder of radius 1 about +z from z = 0 to z = 1, open, its normals outward.
pub fn cylinder() -> RawMesh {
    let mut m = RawMesh { normals: Some(Vec::new()), uvs: Some(Vec::new()), ..Default::default() };
    let k = SEGMENTS as f64;
    for i in 0..=SEGMENTS {
        let phi = TAU * i as f64 / k;
        let n = DVec3::new(phi.cos(), phi.sin(), 0.0);
        for z in [0.0, 1.0] {
            m.positions.push(n + DVec3::Z * z);
            if let (Some(ns), Some(uvs)) = (&mut m.normals, &mut m.uvs) {
                ns.push(n);
                uvs.push(uv(i as f64 / k, z));
            }
        }
    }
    for i in 0..SEGMENTS {
        let (a, b, c, d) = (2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3);
        m.indices.push([a, c, d]);
        m.indices.push([a, d, b]);
    }
    m
}

/// Mitsuba's serialized format's tag.
const SERIALIZED_ID: u16 = 0x041C;

/// Mesh `index` of a Mitsuba `serialized` file.
pub fn serialized(path: &Path, index: usize) -> Result<RawMesh, String> {
    let at = |what: String| format!("{}: {what}", path.display());
    let bytes = std::fs::read(path).map_err(|e| at(e.to_string()))?;
    read_serialized(&bytes, index).map_err(at)
}

fn read_serialized(bytes: &[u8], index: usize) -> Result<RawMesh, String> {
    let u16_at = |k: usize| bytes.get(k..k + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    if u16_at(0) != Some(SERIALIZED_ID) {
        return Err("not a Mitsuba serialized mesh (its first two bytes are not 0x041C)".into());
    }
    let version = u16_at(2).unwrap_or(0);
    if !(3..=4).contains(&version) {
        return Err(format!("serialized format version {version}; lightsplit reads versions 3 and 4"));
    }
    // The dictionary at the end: each mesh's offset, then their count.
    let n = bytes.len();
    let count = bytes.get(n.saturating_sub(4)..).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    let count = count.ok_or("the file is too short")? as usize;
    if index >= count {
        return Err(format!("`shape_index` {index}, but the file holds {count} meshes"));
    }
    let width = if version == 4 { 8 } else { 4 };
    let table = n.checked_sub(4 + width * count).ok_or("the file's mesh table is cut short")?;
    let entry = &bytes[table + width * index..table + width * (index + 1)];
    let offset = if version == 4 {
        u64::from_le_bytes(entry.try_into().map_err(|_| "bad mesh table")?) as usize
    } else {
        u32::from_le_bytes(entry.try_into().map_err(|_| "bad mesh table")?) as usize
    };
    let start = offset.checked_add(4).filter(|&s| s <= table).ok_or("a mesh offset lies outside the file")?;
    let mut z = flate2::read::ZlibDecoder::new(&bytes[start..table]);
    let mut r = Stream { z: &mut z };
    let flags = r.u32()?;
    if version == 4 {
        // The mesh's name, NUL-terminated.
        while r.bytes::<1>()?[0] != 0 {}
    }
    let vertices = r.u64()?;
    let faces = r.u64()?;
    const LIMIT: u64 = 1 << 31;
    if vertices > LIMIT || faces > LIMIT {
        return Err(format!("{vertices} vertices and {faces} faces are more than lightsplit reads"));
    }
    let double = flags & 0x2000 != 0;
    let mut reals = |k: usize| -> Result<Vec<f64>, String> {
        (0..k).map(|_| if double { r.f64() } else { r.f32().map(f64::from) }).collect()
    };
    let v = vertices as usize;
    let p = reals(3 * v)?;
    let triples = |p: Vec<f64>| p.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect::<Vec<_>>();
    let positions = triples(p);
    let normals = if flags & 0x1 != 0 { Some(triples(reals(3 * v)?)) } else { None };
    let uvs = if flags & 0x2 != 0 {
        Some(reals(2 * v)?.chunks_exact(2).map(|c| uv(c[0], c[1])).collect())
    } else {
        None
    };
    if flags & 0x8 != 0 {
        reals(3 * v)?;
    }
    let mut indices = Vec::with_capacity(faces as usize);
    for _ in 0..faces {
        let mut t = [0u32; 3];
        for k in &mut t {
            let i = if vertices > u32::MAX as u64 { r.u64()? } else { r.u32()? as u64 };
            if i >= vertices {
                return Err(format!("a face's vertex {i} is past the {vertices} vertices"));
            }
            *k = i as u32;
        }
        indices.push(t);
    }
    Ok(RawMesh { positions, normals, uvs, indices })
}

struct Stream<'a, R: Read> {
    z: &'a mut R,
}

impl<R: Read> Stream<'_, R> {
    fn bytes<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut b = [0u8; N];
        self.z
            .read_exact(&mut b)
            .map_err(|e| format!("the compressed mesh ends early or is corrupt ({e})"))?;
        Ok(b)
    }
    fn u32(&mut self) -> Result<u32, String> {
        self.bytes().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Result<u64, String> {
        self.bytes().map(u64::from_le_bytes)
    }
    fn f32(&mut self) -> Result<f32, String> {
        self.bytes().map(f32::from_le_bytes)
    }
    fn f64(&mut self) -> Result<f64, String> {
        self.bytes().map(f64::from_le_bytes)
    }
}

#[cfg(test)]
pub mod tests {
    use super::*;

    /// A serialized file of `meshes` (version 4, single precision, normals and uvs).
    pub fn write_serialized(meshes: &[RawMesh]) -> Vec<u8> {
        use std::io::Write;
        let mut out = Vec::new();
        let mut offsets = Vec::new();
        for m in meshes {
            offsets.push(out.len() as u64);
            out.extend(SERIALIZED_ID.to_le_bytes());
            out.extend(4u16.to_le_bytes());
            let mut raw = Vec::new();
            raw.extend((0x1000u32 | 0x1 | 0x2).to_le_bytes());
            raw.extend(b"mesh\0");
            raw.extend((m.positions.len() as u64).to_le_bytes());
            raw.extend((m.indices.len() as u64).to_le_bytes());
            for p in &m.positions {
                for c in p.to_array() {
                    raw.extend((c as f32).to_le_bytes());
                }
            }
            for n in m.normals.clone().unwrap_or_else(|| vec![DVec3::Z; m.positions.len()]) {
                for c in n.to_array() {
                    raw.extend((c as f32).to_le_bytes());
                }
            }
            for t in m.uvs.clone().unwrap_or_else(|| vec![DVec2::ZERO; m.positions.len()]) {
                raw.extend((t.x as f32).to_le_bytes());
                raw.extend(((1.0 - t.y) as f32).to_le_bytes());
            }
            for t in &m.indices {
                for i in t {
                    raw.extend(i.to_le_bytes());
                }
            }
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
            z.write_all(&raw).unwrap();
            out.extend(z.finish().unwrap());
        }
        for o in &offsets {
            out.extend(o.to_le_bytes());
        }
        out.extend((meshes.len() as u32).to_le_bytes());
        out
    }

    #[test]
    fn serialized_meshes_read_back_by_index() {
        let (a, b) = (rectangle(), cube());
        let bytes = write_serialized(&[a.clone(), b.clone()]);
        for (k, m) in [a, b].iter().enumerate() {
            let r = read_serialized(&bytes, k).unwrap();
            assert_eq!(r.indices, m.indices);
            assert_eq!(r.positions, m.positions);
            let uvs = r.uvs.unwrap();
            assert!(uvs
                .iter()
                .zip(m.uvs.as_ref().unwrap())
                .all(|(p, q)| (*p - *q).abs().max_element() < 1e-6));
        }
        let e = read_serialized(&bytes, 2).unwrap_err();
        assert!(e.contains("holds 2 meshes"), "{e}");
        let e = read_serialized(&bytes[..bytes.len() / 2], 0).unwrap_err();
        assert!(!e.is_empty());
        assert!(read_serialized(b"nope", 0).unwrap_err().contains("0x041C"));
    }

    fn area(m: &RawMesh) -> f64 {
        m.indices
            .iter()
            .map(|t| {
                let p = t.map(|i| m.positions[i as usize]);
                0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length()
            })
            .sum()
    }

    #[test]
    fn analytic_shapes_have_their_areas_and_face_outward() {
        let pi = std::f64::consts::PI;
        for (name, m, want) in [
            ("rectangle", rectangle(), 4.0),
            ("cube", cube(), 24.0),
            ("disk", disk(), pi),
            ("cylinder", cylinder(), 2.0 * pi),
        ] {
            let a = area(&m);
            assert!((a / want - 1.0).abs() < 1e-4, "{name}: area {a}, want {want}");
            // Each triangle's winding agrees with its vertices' normals.
            let ns = m.normals.as_ref().unwrap();
            for t in &m.indices {
                let p = t.map(|i| m.positions[i as usize]);
                let g = (p[1] - p[0]).cross(p[2] - p[0]);
                assert!(g.dot(ns[t[0] as usize]) > 0.0, "{name}: a triangle faces inward");
            }
        }
        // The cube faces away from its centre.
        let c = cube();
        for t in &c.indices {
            let p = t.map(|i| c.positions[i as usize]);
            assert!((p[1] - p[0]).cross(p[2] - p[0]).dot(p[0] + p[1] + p[2]) > 0.0);
        }
    }
}
