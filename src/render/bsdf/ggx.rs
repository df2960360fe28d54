//! The GGX microfacet pieces every glossy material shares: the lobes in the local shading frame
//! (the height-correlated shadowing-masking term, sampled by its distribution of visible
//! normals: Heitz 2018, "Sampling the GGX Distribution of Visible Normals") and the split-sum
//! table of a lobe's directional albedo.

use std::f32::consts::{PI, TAU};

use glam::{Vec2, Vec3};

use super::Lobe;
#[cfg(test)]
use super::MIN_ALPHA;
use crate::math::{cosine_hemisphere, luminance};

/// The directional albedo of a GGX lobe with Schlick's Fresnel, split as f0 A + B (the
/// "split-sum" table of real-time rendering): A and B by the cosine of the view (indexed by its
/// square root, finer toward grazing, where the albedo changes fastest) and the GGX alpha (by
/// its square root, the perceptual roughness, finer where the lobe is sharp), 32 x 32 cells, integrated once by sampling visible normals (1,024 stratified points a
/// cell, crowded toward the steep normals) and read bilinearly.
pub struct SpecularAlbedo {
    table: Vec<(f32, f32)>,
    /// Each alpha row's hemispherical average of the white albedo, 2 int E(mu) mu dmu.
    average: Vec<f32>,
}

impl SpecularAlbedo {
    const N: usize = 32;

    /// The table, as stored in `tables/specular-albedo.bin` (A and B of each cell, row by row of
    /// alpha, as little-endian f32), decoded on first use. Integrating it takes tens of
    /// milliseconds, which a short render would pay; a test checks that the stored table is
    /// what [`SpecularAlbedo::build`] integrates.
    pub fn get() -> &'static SpecularAlbedo {
        static TABLE: std::sync::OnceLock<SpecularAlbedo> = std::sync::OnceLock::new();
        TABLE.get_or_init(|| {
            let floats = super::stored_table(include_bytes!("tables/specular-albedo.bin"));
            SpecularAlbedo::new(floats.chunks_exact(2).map(|c| (c[0], c[1])).collect())
        })
    }

    /// The table and its rows' averages.
    fn new(table: Vec<(f32, f32)>) -> SpecularAlbedo {
        let n = Self::N;
        // 2 int_0^1 E(mu) mu dmu with mu = x^2: 4 int_0^1 E(x^2) x^3 dx, by the trapezoid rule
        // over the row's cells (x = i / (n - 1)).
        let average = (0..n)
            .map(|j| {
                let f = |i: usize| {
                    let (a, b) = table.get(j * n + i).copied().unwrap_or((0.0, 0.0));
                    let x = i as f32 / (n - 1) as f32;
                    4.0 * (a + b) * x * x * x
                };
                let inner: f32 = (1..n - 1).map(f).sum();
                (inner + 0.5 * (f(0) + f(n - 1))) / (n - 1) as f32
            })
            .collect();
        SpecularAlbedo { table, average }
    }

    /// The average white albedo over the hemisphere at alpha `alpha`, linearly.
    fn average(&self, alpha: f32) -> f32 {
        let n = Self::N;
        let y = (alpha.clamp(0.0, 1.0).sqrt() * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let j = y as usize;
        let (p, q) =
            (self.average.get(j).copied().unwrap_or(1.0), self.average.get(j + 1).copied().unwrap_or(1.0));
        p + (q - p) * (y - j as f32)
    }

    /// The table's values, A and B of each cell in order, for storing.
    #[cfg(test)]
    pub(super) fn values(&self) -> Vec<f32> {
        self.table.iter().flat_map(|&(a, b)| [a, b]).collect()
    }

    /// The table, integrated.
    #[cfg(test)]
    pub(super) fn build() -> SpecularAlbedo {
        let n = Self::N;
        let mut table = Vec::with_capacity(n * n);
        for j in 0..n {
            let y = j as f32 / (n - 1) as f32;
            let alpha = (y * y).max(MIN_ALPHA);
            for i in 0..n {
                let x = i as f32 / (n - 1) as f32;
                let cos = (x * x).max(1e-3);
                let wo = Vec3::new((1.0 - cos * cos).sqrt(), 0.0, cos);
                let g = GlossyLobes { specular: Vec3::ONE, alpha, base: Vec3::ZERO };
                let (mut a, mut b) = (0.0f64, 0.0f64);
                let k = 32;
                for s in 0..k * k {
                    // The radius on the projected disk, u.x = 1 - (1 - v)^2: strata crowd toward
                    // its rim, where the steepest visible normals send light below the surface
                    // (the tail that uniform strata miss at low alpha), each weighted by the
                    // map's Jacobian 2 (1 - v).
                    let v = ((s % k) as f32 + 0.5) / k as f32;
                    let u = Vec2::new(1.0 - (1.0 - v) * (1.0 - v), ((s / k) as f32 + 0.5) / k as f32);
                    let wi = g.sample_specular(wo, u);
                    if wi.z <= 0.0 {
                        continue;
                    }
                    let h = (wo + wi).normalize_or_zero();
                    let w = (g.g2(wo, wi) / g.g1(wo)) as f64 * 2.0 * (1.0 - v) as f64;
                    let m = (1.0 - wo.dot(h)).clamp(0.0, 1.0) as f64;
                    let fresnel = m.powi(5);
                    a += w * (1.0 - fresnel);
                    b += w * fresnel;
                }
                let total = (k * k) as f64;
                table.push(((a / total) as f32, (b / total) as f32));
            }
        }
        SpecularAlbedo::new(table)
    }

    /// (A, B) and the average white albedo, at view cosine `cos` and alpha `alpha`.
    pub fn lookup(&self, cos: f32, alpha: f32) -> (f32, f32, f32) {
        let (a, b) = self.at(cos, alpha);
        (a, b, self.average(alpha))
    }

    /// The factor that restores the energy single-scattering GGX loses between its microfacets,
    /// 1 + F_ms (1 - e) / e (Turquin 2019, "Practical multiple scattering compensation for
    /// microfacet models"), `e` being the albedo of the lobe with a white Fresnel (`e_avg` its hemispherical average), and the
    /// Fresnel of the light that bounces between facets F_ms = F_avg E_avg / (1 - F_avg
    /// (1 - E_avg)) (Kulla & Conty 2017: each further bounce is reflected with the average
    /// Fresnel F_avg = f0 + (1 - f0) / 21 of Schlick's, and escapes with the average albedo
    /// E_avg). A white metal reflects all the light; a coloured one loses what its bounces
    /// absorb; a dielectric lobe (small f0) gains little.
    pub fn compensation(&self, f0: Vec3, e: f32, e_avg: f32) -> Vec3 {
        let (e, e_avg) = (e.clamp(1e-3, 1.0), e_avg.clamp(1e-3, 1.0));
        let f_avg = f0 + (Vec3::ONE - f0) / 21.0;
        let f_ms = f_avg * e_avg / (Vec3::ONE - f_avg * (1.0 - e_avg));
        Vec3::ONE + f_ms * ((1.0 - e) / e)
    }

    /// (A, B) at view cosine `cos` and alpha `alpha`, bilinearly.
    pub fn at(&self, cos: f32, alpha: f32) -> (f32, f32) {
        let n = Self::N;
        let x = (cos.clamp(0.0, 1.0).sqrt() * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let y = (alpha.clamp(0.0, 1.0).sqrt() * (n - 1) as f32).min((n - 1) as f32 - 1e-4);
        let (i, j) = (x as usize, y as usize);
        let (fx, fy) = (x - i as f32, y - j as f32);
        let t = |i: usize, j: usize| self.table[j * n + i];
        let lerp = |p: (f32, f32), q: (f32, f32), f: f32| (p.0 + (q.0 - p.0) * f, p.1 + (q.1 - p.1) * f);
        lerp(lerp(t(i, j), t(i + 1, j), fx), lerp(t(i, j + 1), t(i + 1, j + 1), fx), fy)
    }
}

/// The glossy model in the local shading frame (z along the normal): a GGX lobe with
/// reflectance `specular` at normal incidence, over a diffuse `base`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GlossyLobes {
    pub specular: Vec3,
    pub alpha: f32,
    pub base: Vec3,
}

/// Schlick's approximation of the Fresnel reflectance.
fn schlick(f0: Vec3, cos: f32) -> Vec3 {
    schlick_to(f0, Vec3::ONE, cos)
}

/// Schlick's Fresnel from `f0` at normal incidence to `f90` at grazing (glTF's
/// `KHR_materials_specular` lowers f90 below 1).
pub(super) fn schlick_to(f0: Vec3, f90: Vec3, cos: f32) -> Vec3 {
    let m = (1.0 - cos).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (f90 - f0) * (m2 * m2 * m)
}

impl GlossyLobes {
    /// GGX normal distribution of microfacet normal `m`.
    pub(super) fn d(&self, m: Vec3) -> f32 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let a2 = self.alpha * self.alpha;
        let t = m.z * m.z * (a2 - 1.0) + 1.0;
        a2 / (PI * t * t)
    }

    /// Smith's Lambda for direction `w`.
    fn lambda(&self, w: Vec3) -> f32 {
        let c2 = w.z * w.z;
        if c2 == 0.0 {
            return f32::INFINITY;
        }
        let tan2 = (1.0 - c2).max(0.0) / c2;
        0.5 * ((1.0 + self.alpha * self.alpha * tan2).sqrt() - 1.0)
    }

    pub(super) fn g1(&self, w: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(w))
    }

    /// Height-correlated masking and shadowing.
    pub(super) fn g2(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.0 / (1.0 + self.lambda(wo) + self.lambda(wi))
    }

    /// The probability of sampling the GGX lobe rather than the base, seen from `wo`: in
    /// proportion to the light each reflects, so a dark base takes few samples.
    pub fn specular_probability(&self, wo: Vec3) -> f32 {
        let spec = luminance(schlick(self.specular, wo.z));
        let base = luminance(self.base * (Vec3::ONE - self.specular));
        if base <= 0.0 {
            1.0
        } else if spec <= 0.0 {
            0.0
        } else {
            spec / (spec + base)
        }
    }

    /// The GGX lobe's BRDF (zero unless both directions are above the surface).
    pub fn eval_specular(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        let f = schlick(self.specular, wo.dot(h));
        f * (self.d(h) * self.g2(wo, wi) / (4.0 * wo.z * wi.z))
    }

    /// The density of [`GlossyLobes::sample_specular`] in solid angle (defined below the horizon
    /// too, where visible-normal sampling can send a direction).
    pub fn pdf_specular(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z <= 0.0 {
            return 0.0;
        }
        let h = (wo + wi).normalize_or_zero();
        if wo.dot(h) <= 0.0 {
            return 0.0;
        }
        self.g1(wo) * self.d(h) / (4.0 * wo.z)
    }

    /// A microfacet normal seen from `wo` (above the surface), by the distribution of visible
    /// normals: density G1(wo) max(0, wo.m) D(m) / wo.z.
    pub fn visible_normal(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let a = self.alpha;
        // The view direction in the hemisphere configuration (alpha = 1).
        let vh = Vec3::new(a * wo.x, a * wo.y, wo.z).normalize();
        let len2 = vh.x * vh.x + vh.y * vh.y;
        let t1 = if len2 > 0.0 { Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt() } else { Vec3::X };
        let t2 = vh.cross(t1);
        // A point on the projected half disk.
        let r = u.x.sqrt();
        let phi = TAU * u.y;
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * vh;
        // Back to the ellipsoid configuration.
        Vec3::new(a * nh.x, a * nh.y, nh.z.max(0.0)).normalize()
    }

    /// A direction from the GGX lobe by sampling a visible microfacet normal and reflecting.
    pub fn sample_specular(&self, wo: Vec3, u: Vec2) -> Vec3 {
        let m = self.visible_normal(wo, u);
        2.0 * wo.dot(m) * m - wo
    }

    /// The GGX lobe's f cos / pdf for a direction it sampled: F G2 / G1 (D cancels).
    pub fn specular_weight(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wo + wi).normalize_or_zero();
        schlick(self.specular, wo.dot(h)) * (self.g2(wo, wi) / self.g1(wo))
    }

    /// The diffuse base's BRDF (Ashikhmin-Shirley): what the coating lets through, twice.
    pub fn eval_base(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let through = |c: f32| {
            let m = 1.0 - 0.5 * c;
            let m2 = m * m;
            1.0 - m2 * m2 * m
        };
        self.base * (Vec3::ONE - self.specular) * (28.0 / (23.0 * PI) * through(wo.z) * through(wi.z))
    }

    /// The base is sampled by the cosine.
    pub fn pdf_base(&self, wi: Vec3) -> f32 {
        wi.z.max(0.0) / PI
    }

    pub fn sample_base(&self, u: Vec2) -> Vec3 {
        cosine_hemisphere(u)
    }

    /// The whole BRDF.
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.eval_specular(wo, wi) + self.eval_base(wo, wi)
    }

    /// The density of [`GlossyLobes::sample`], both lobes together.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let p = self.specular_probability(wo);
        p * self.pdf_specular(wo, wi) + (1.0 - p) * self.pdf_base(wi)
    }

    /// Picks a lobe with `u_lobe`, then a direction from it.
    pub fn sample(&self, wo: Vec3, u_lobe: f32, u: Vec2) -> (Vec3, Lobe) {
        if u_lobe < self.specular_probability(wo) {
            (self.sample_specular(wo, u), Lobe::Specular)
        } else {
            (self.sample_base(u), Lobe::Diffuse)
        }
    }
}
