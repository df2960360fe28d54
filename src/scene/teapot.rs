//! The Utah teapot from Martin Newell's 32 bicubic Bezier patches (the public-domain data in
//! `data/teapot.txt`), tessellated into a welded triangle mesh with smooth normals. Each patch is
//! evaluated as a curve of curves, so two patches that share a boundary evaluate it to the same
//! bits and welding by position closes every seam. Triangles that collapse at the cusps (the
//! lid's knob and the bottom's centre, where a patch row is one point) are dropped.

use std::collections::HashMap;

use glam::{Vec3, Vec3A};

use super::Mesh;

const DATA: &str = include_str!("data/teapot.txt");

/// The control points of the 32 patches, 4x4 each (row-major: `[u][v]`).
pub fn patches() -> Vec<[[Vec3; 4]; 4]> {
    let mut lines = DATA.lines().map(str::trim).filter(|l| !l.is_empty() && !l.starts_with('#'));
    let n = count(lines.next(), "patches");
    let indices: Vec<Vec<usize>> = (0..n).map(|_| numbers(lines.next())).collect();
    let n = count(lines.next(), "vertices");
    let vertices: Vec<Vec3> = (0..n)
        .map(|_| {
            let v: Vec<f32> = numbers(lines.next());
            Vec3::new(v[0], v[1], v[2])
        })
        .collect();
    indices
        .iter()
        .map(|row| std::array::from_fn(|u| std::array::from_fn(|v| vertices[row[4 * u + v] - 1])))
        .collect()
}

/// The count of a section header line `NAME COUNT`.
fn count(line: Option<&str>, name: &str) -> usize {
    line.and_then(|l| l.strip_prefix(name)).and_then(|n| n.trim().parse().ok()).unwrap_or(0)
}

/// The whitespace-separated numbers of a line.
fn numbers<T: std::str::FromStr>(line: Option<&str>) -> Vec<T> {
    line.unwrap_or_default().split_whitespace().filter_map(|v| v.parse().ok()).collect()
}

/// The cubic Bernstein weights at t.
fn bernstein(t: f32) -> [f32; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * t * s * s, 3.0 * t * t * s, t * t * t]
}

/// A point of a bicubic patch: the v-curves first, then the u-curve through them.
fn eval(p: &[[Vec3; 4]; 4], u: f32, v: f32) -> Vec3 {
    let (bu, bv) = (bernstein(u), bernstein(v));
    let mut out = Vec3::ZERO;
    for (i, row) in p.iter().enumerate() {
        // A row collapsed to one point (a cusp) is that point exactly, whatever the rounding of
        // the weights: so the cusp welds into one vertex and its triangles drop out.
        let c = if row.iter().all(|q| *q == row[0]) {
            row[0]
        } else {
            row.iter().zip(bv).fold(Vec3::ZERO, |c, (q, b)| c + *q * b)
        };
        out += c * bu[i];
    }
    out
}

/// The teapot tessellated with `n` x `n` quads (2 n^2 triangles) a patch, less the collapsed
/// triangles at the cusps; z up as in Newell's data, turned here to y up, standing on y = 0.
pub fn teapot(n: u32) -> Mesh {
    let n = n.max(1) as usize;
    let mut positions: Vec<Vec3> = Vec::new();
    let mut index_of: HashMap<[u32; 3], u32> = HashMap::new();
    let mut weld = |p: Vec3| -> u32 {
        // z up to y up: (x, y, z) -> (x, z, -y), a rotation.
        let p = Vec3::new(p.x, p.z, -p.y);
        // One vertex for +0 and -0.
        let key = (p + Vec3::ZERO).to_array().map(f32::to_bits);
        *index_of.entry(key).or_insert_with(|| {
            positions.push(p);
            (positions.len() - 1) as u32
        })
    };
    let mut indices: Vec<[u32; 3]> = Vec::new();
    for patch in patches() {
        let grid: Vec<u32> = (0..=n)
            .flat_map(|i| (0..=n).map(move |j| (i, j)))
            .map(|(i, j)| weld(eval(&patch, i as f32 / n as f32, j as f32 / n as f32)))
            .collect();
        for i in 0..n {
            for j in 0..n {
                let a = grid[i * (n + 1) + j];
                let b = grid[(i + 1) * (n + 1) + j];
                let c = grid[(i + 1) * (n + 1) + j + 1];
                let d = grid[i * (n + 1) + j + 1];
                // Wound so that faces point out of the teapot.
                for t in [[a, c, b], [a, d, c]] {
                    // Collapsed at a cusp: two corners welded into one.
                    if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                        indices.push(t);
                    }
                }
            }
        }
    }
    // Smooth normals: the angle-independent, area-weighted mean of the faces around a vertex.
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for t in &indices {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let face = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += face;
        }
    }
    let normals: Vec<Vec3> = normals.into_iter().map(|n| n.normalize_or(Vec3::Y)).collect();
    Mesh {
        positions: positions.into_iter().map(Vec3A::from).collect(),
        indices: indices.into(),
        normals: Some(normals.into()),
        uvs: None,
        attributes: None,
        instance: None,
        world: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_data_has_32_patches_over_306_points() {
        let p = patches();
        assert_eq!(p.len(), 32);
        // The teapot spans x in [-3, 3.525] and z (Newell's up) in [0, 3.15].
        let all: Vec<Vec3> = p.iter().flatten().flatten().copied().collect();
        let lo = all.iter().fold(Vec3::splat(f32::MAX), |a, b| a.min(*b));
        let hi = all.iter().fold(Vec3::splat(f32::MIN), |a, b| a.max(*b));
        assert_eq!((lo.x, hi.x, lo.z, hi.z), (-3.0, 3.525, 0.0, 3.15));
    }

    #[test]
    fn triangle_count_is_64_n_squared_less_the_cusps() {
        // Eight patches (four of the lid's knob, four of the bottom) have a row collapsed to one
        // point: n triangles each vanish.
        for n in [1u32, 2, 4, 8] {
            let mesh = teapot(n);
            let n = n as usize;
            assert_eq!(mesh.indices.len(), 64 * n * n - 8 * n, "n = {n}");
        }
    }

    #[test]
    fn winding_is_consistent_and_normals_face_outward() {
        let mesh = teapot(8);
        // Every directed edge is used once at most: a neighbour across an edge runs it the
        // other way, so the faces agree on which side is out.
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in mesh.indices.iter() {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        let twice: Vec<_> = directed.iter().filter(|(_, &c)| c > 1).collect();
        assert!(twice.is_empty(), "{} directed edges used twice, e.g. {:?}", twice.len(), twice.first());
        // Outward: on the body (away from handle, spout and lid), faces point away from the axis.
        let p = |i: u32| Vec3::from(mesh.positions[i as usize]);
        let mut outward = 0;
        let mut body = 0;
        for t in mesh.indices.iter() {
            let [a, b, c] = t.map(p);
            let centre = (a + b + c) / 3.0;
            let radial = Vec3::new(centre.x, 0.0, centre.z);
            if centre.y > 0.5 && centre.y < 2.0 && radial.length() > 1.6 && centre.x.abs() < 1.5 {
                body += 1;
                if (b - a).cross(c - a).dot(radial) > 0.0 {
                    outward += 1;
                }
            }
        }
        assert!(body > 50 && outward == body, "{outward} of {body} body faces point outward");
        // Smooth normals are unit length.
        let normals = mesh.normals.as_ref().expect("normals");
        assert!(normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-4));
    }
}
