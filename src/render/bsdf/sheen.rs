//! The sheen of cloth and dust (`KHR_materials_sheen`): the "Charlie" microfiber distribution
//! (Estevez & Kulla 2017, "Production Friendly Microfacet Sheen BRDF") with Ashikhmin's
//! visibility term, as the glTF specification defines the lobe, and the table of its directional
//! albedo by which the layers below it are dimmed.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use crate::math::cosine_hemisphere;

/// The smallest sheen alpha: below it the distribution's exponent 1/alpha makes it a spike at
/// the horizon that f32 cannot integrate.
const MIN_ALPHA: f32 = 0.07;

/// A sheen lobe in the local shading frame (z along the normal): colour times the Charlie
/// distribution of the half vector times Ashikhmin's visibility, sampled by the cosine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SheenLobe {
    pub color: Vec3,
    /// The distribution's alpha: the perceptual roughness squared, as glTF's.
    pub alpha: f32,
}

impl SheenLobe {
    pub fn new(color: Vec3, roughness: f32) -> SheenLobe {
        SheenLobe { color, alpha: (roughness * roughness).max(MIN_ALPHA) }
    }

    /// The BRDF, with a white colour.
    pub(super) fn value(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize_or_zero();
        let sin2 = (1.0 - h.z * h.z).max(0.0);
        let inv = 1.0 / self.alpha;
        let d = (2.0 + inv) * sin2.powf(0.5 * inv) / TAU;
        let v = 1.0 / (4.0 * (wi.z + wo.z - wi.z * wo.z));
        d * v
    }

    pub fn pdf(&self, wi: Vec3) -> f32 {
        wi.z.max(0.0) / PI
    }

    pub fn sample(&self, u: Vec2) -> Vec3 {
        cosine_hemisphere(u)
    }
}

/// The directional albedo of a white sheen lobe by the cosine of the view and the perceptual
/// roughness: 32 x 32 cells, each integrated once over 32 x 32 cosine-stratified directions,
/// read bilinearly. The view cosine is indexed by its square root, where the albedo changes
/// fastest (toward grazing).
pub struct SheenAlbedo {
    table: Vec<f32>,
}

impl SheenAlbedo {
    const N: usize = 32;

    /// The table, as stored in `tables/sheen-albedo.bin` (row by row of roughness, little-endian
    /// f32), decoded on first use; a test checks that it is what [`SheenAlbedo::build`]
    /// integrates.
    pub fn get() -> &'static SheenAlbedo {
        static TABLE: std::sync::OnceLock<SheenAlbedo> = std::sync::OnceLock::new();
        TABLE.get_or_init(|| SheenAlbedo {
            table: super::stored_table(include_bytes!("tables/sheen-albedo.bin")),
        })
    }

    /// The table's values in order, for storing.
    #[cfg(test)]
    pub(super) fn values(&self) -> Vec<f32> {
        self.table.clone()
    }

    /// The albedo the table holds for view cosine `cos`, roughness `roughness`, exactly.
    #[cfg(test)]
    pub(super) fn integrate(cos: f32, roughness: f32, k: usize) -> f32 {
        let lobe = SheenLobe::new(Vec3::ONE, roughness);
        let cos = cos.max(1e-3);
        let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
        // Over the hemisphere of wi.z = v^2 (crowding toward the horizon, where the lobe
        // lies) and phi in [0, pi] (the lobe is symmetric about the plane of wo), midpoints:
        // E = 2 * int_0^1 int_0^pi f v^2 2v dphi dv.
        let mut sum = 0.0f64;
        for j in 0..k {
            let v = (j as f32 + 0.5) / k as f32;
            let z = v * v;
            let r = (1.0 - z * z).max(0.0).sqrt();
            for i in 0..k {
                let phi = (i as f32 + 0.5) / k as f32 * PI;
                let wi = Vec3::new(r * phi.cos(), r * phi.sin(), z);
                sum += (lobe.value(wo, wi) * z * 2.0 * v) as f64;
            }
        }
        (sum * 2.0 * PI as f64 / (k * k) as f64) as f32
    }

    /// The table, integrated.
    #[cfg(test)]
    pub(super) fn build() -> SheenAlbedo {
        let n = Self::N;
        let mut table = Vec::with_capacity(n * n);
        for j in 0..n {
            let roughness = j as f32 / (n - 1) as f32;
            for i in 0..n {
                let x = i as f32 / (n - 1) as f32;
                table.push(Self::integrate(x * x, roughness, 32));
            }
        }
        SheenAlbedo { table }
    }

    /// The albedo at view cosine `cos` and perceptual roughness `roughness`, bilinearly.
    pub fn at(&self, cos: f32, roughness: f32) -> f32 {
        let n = Self::N;
        let x = (cos.clamp(0.0, 1.0).sqrt() * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let y = (roughness.clamp(0.0, 1.0) * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let (i, j) = (x as usize, y as usize);
        let (fx, fy) = (x - i as f32, y - j as f32);
        let t = |i: usize, j: usize| self.table[j * n + i];
        let lerp = |p: f32, q: f32, f: f32| p + (q - p) * f;
        lerp(lerp(t(i, j), t(i + 1, j), fx), lerp(t(i, j + 1), t(i + 1, j + 1), fx), fy)
    }
}
