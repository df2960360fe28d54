//! The cloudy sky as a table: its radiance at the centres of cells of equal solid angle over
//! the upper hemisphere, and a distribution over those cells for importance sampling (the
//! procedural clouds cost too much to evaluate at every vertex).

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use crate::math::{luminance, Distribution2D};
use crate::scene::sky::CloudySky;

/// Cells of the cloudy sky's tables: in cos theta (horizon to zenith) and in phi.
const SKY_ROWS: usize = 256;
const SKY_COLUMNS: usize = 1024;

/// The direction of a point of the sky table's square: u = phi / 2 pi, v = cos theta.
pub fn sky_direction(uv: Vec2) -> Vec3 {
    let (sin_phi, cos_phi) = crate::math::sin_cos_turn(uv.x);
    let cos = uv.y;
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    Vec3::new(sin * cos_phi, cos, sin * sin_phi)
}

/// The radiance of the sky table at a point of its square: bilinear between cell centres,
/// wrapping around in phi and clamped at the horizon and the zenith.
pub fn sky_lookup(radiance: &[Vec3], uv: Vec2) -> Vec3 {
    let x = uv.x * SKY_COLUMNS as f32 - 0.5;
    let y = (uv.y * SKY_ROWS as f32 - 0.5).clamp(0.0, (SKY_ROWS - 1) as f32);
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let col = |c: f32| (c as i64).rem_euclid(SKY_COLUMNS as i64) as usize;
    let (c0, c1) = (col(x0), col(x0 + 1.0));
    let (r0, r1) = (y0 as usize, (y0 as usize + 1).min(SKY_ROWS - 1));
    let at = |r: usize, c: usize| radiance[r * SKY_COLUMNS + c];
    (at(r0, c0) * (1.0 - fx) + at(r0, c1) * fx) * (1.0 - fy)
        + (at(r1, c0) * (1.0 - fx) + at(r1, c1) * fx) * fy
}

/// The tables of a cloudy sky: the sampling distribution (the luminance at each cell's centre,
/// plus a floor of a tenth of the mean so that no direction the sky lights is left out), the
/// radiance at the cell centres, and the mean luminance.
pub fn sky_table(sky: &CloudySky) -> (Distribution2D, Vec<Vec3>, f32) {
    let radiance: Vec<Vec3> = (0..SKY_ROWS * SKY_COLUMNS)
        .into_par_iter()
        .map(|i| {
            let (col, row) = (i % SKY_COLUMNS, i / SKY_COLUMNS);
            let uv = Vec2::new((col as f32 + 0.5) / SKY_COLUMNS as f32, (row as f32 + 0.5) / SKY_ROWS as f32);
            sky.radiance(sky_direction(uv))
        })
        .collect();
    let lum: Vec<f32> = radiance.iter().map(|&r| luminance(r)).collect();
    let mean = lum.iter().sum::<f32>() / lum.len() as f32;
    let floor = 0.1 * mean.max(1e-12);
    let weights: Vec<f32> = lum.iter().map(|l| l + floor).collect();
    let table = Distribution2D::new(&weights, SKY_COLUMNS, SKY_ROWS).unwrap_or_else(|| {
        Distribution2D::new(&vec![1.0; SKY_ROWS * SKY_COLUMNS], SKY_COLUMNS, SKY_ROWS).expect("uniform")
    });
    (table, radiance, mean)
}
