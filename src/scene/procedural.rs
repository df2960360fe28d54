//! Geometry generated in code: a fractal terrain of any size, for measuring how the
//! accelerators scale (no large files in the repository).

use glam::{Vec3, Vec3A};
use rayon::prelude::*;

use super::noise::fbm;
use super::Mesh;

/// A square height field of `resolution` x `resolution` cells (2 resolution^2 triangles) over
/// `size` x `size` units centred on the origin in x and z, with fBm heights up to `height`.
pub fn terrain(resolution: u32, size: f32, height: f32, seed: u32) -> Mesh {
    let n = resolution as usize + 1;
    let positions: Vec<Vec3A> = (0..n * n)
        .into_par_iter()
        .map(|i| {
            let (x, z) = ((i % n) as f32 / resolution as f32 - 0.5, (i / n) as f32 / resolution as f32 - 0.5);
            let y = height * fbm(seed, Vec3::new(x * 6.0, 0.37, z * 6.0), 10, 0.5);
            Vec3A::new(x * size, y, z * size)
        })
        .collect();
    let r = resolution as usize;
    let indices: Vec<[u32; 3]> = (0..r * r)
        .into_par_iter()
        .flat_map_iter(|c| {
            let (i, j) = (c % r, c / r);
            let a = (j * n + i) as u32;
            let (b, d, e) = (a + 1, a + n as u32, a + n as u32 + 1);
            // Counter-clockwise seen from above (+y).
            [[a, d, e], [a, e, b]]
        })
        .collect();
    Mesh::new(positions.into(), indices.into(), None, None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn terrain_has_the_asked_size_and_faces_up() {
        let m = terrain(10, 4.0, 1.0, 3);
        assert_eq!(m.indices.len(), 200);
        assert_eq!(m.positions.len(), 121);
        for t in 0..m.indices.len() as u32 {
            let [a, b, c] = m.triangle(t);
            assert!((b - a).cross(c - a).y > 0.0, "triangle {t} faces down");
        }
        let heights: Vec<f32> = m.positions.iter().map(|p| p.y).collect();
        assert!(heights.iter().all(|h| h.abs() <= 1.0));
        assert!(heights.iter().any(|h| h.abs() > 0.05), "flat terrain");
    }
}
