//! The paper's cloudy sky (its test scene 1): the CIE standard overcast sky, whose luminance
//! grows from the horizon to the zenith as (1 + 2 cos theta) / 3, with procedural clouds (fBm
//! noise on a plane high above the scene) that modulate its radiance and show in the
//! background. The up direction is +y; nothing comes from below the horizon.

use glam::{Vec2, Vec3};

use super::noise::fbm;

/// A cloudy CIE overcast sky.
#[derive(Clone, Debug, PartialEq)]
pub struct CloudySky {
    /// The radiance of a cloud at the zenith.
    pub zenith: Vec3,
    /// The radiance of the clear sky between the clouds, at the zenith.
    pub clear: Vec3,
    /// The fraction of the sky the clouds cover, in [0, 1].
    pub cover: f32,
    /// The size of the clouds: the noise's feature size on the cloud plane, in units of the
    /// plane's height.
    pub scale: f32,
    pub seed: u32,
}

impl CloudySky {
    /// The cloud density (0 clear, 1 cloud) seen along a direction with `dir.y > 0`.
    pub fn density(&self, dir: Vec3) -> f32 {
        // Where the ray meets the cloud plane at height 1, in units of the feature size.
        let q = Vec2::new(dir.x, dir.z) / (dir.y.max(1e-3) * self.scale.max(1e-6));
        // Six octaves of fBm are close to normal with a spread of 0.17 (measured); the threshold
        // above which a fraction `cover` of it lies, by the logistic approximation of the
        // normal quantile, with a soft edge 0.1 wide.
        let n = fbm(self.seed, Vec3::new(q.x, 0.37, q.y), 6, 0.5);
        let c = self.cover.clamp(1e-3, 1.0 - 1e-3);
        let threshold = 0.17 * 0.5513 * ((1.0 - c) / c).ln();
        let t = ((n - threshold) / 0.1 + 0.5).clamp(0.0, 1.0);
        let density = t * t * (3.0 - 2.0 * t);
        // Toward the horizon the clouds shrink below a pixel; there they fade into their mean
        // cover instead of flickering.
        let h = (dir.y / 0.12).clamp(0.0, 1.0);
        let fade = h * h * (3.0 - 2.0 * h);
        self.cover + (density - self.cover) * fade
    }

    /// The radiance arriving from direction `dir` (unit).
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        if dir.y <= 0.0 {
            return Vec3::ZERO;
        }
        let gradation = (1.0 + 2.0 * dir.y) / 3.0;
        self.clear.lerp(self.zenith, self.density(dir)) * gradation
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overcast_gradation_and_clouds() {
        // Without clouds (cover 0, all clear) the zenith is 3x the horizon, as CIE says.
        let clear = CloudySky { zenith: Vec3::ONE, clear: Vec3::ONE, cover: 0.0, scale: 1.0, seed: 1 };
        let z = clear.radiance(Vec3::Y).x;
        let h = clear.radiance(Vec3::new(1.0, 1e-6, 0.0).normalize()).x;
        assert!((z - 1.0).abs() < 1e-6 && (h - 1.0 / 3.0).abs() < 1e-4, "{z} {h}");
        assert_eq!(clear.radiance(-Vec3::Y), Vec3::ZERO);
        // Clouds cover about the asked fraction of the sky seen near the zenith.
        for cover in [0.3f32, 0.7] {
            let sky = CloudySky { zenith: Vec3::ONE, clear: Vec3::ZERO, cover, scale: 0.3, seed: 2 };
            let mut sum = 0.0;
            let n = 200;
            for i in 0..n {
                for j in 0..n {
                    let d = Vec3::new(2.0 * i as f32 / n as f32 - 1.0, 1.0, 2.0 * j as f32 / n as f32 - 1.0)
                        .normalize();
                    sum += sky.density(d);
                }
            }
            let measured = sum / (n * n) as f32;
            assert!((measured - cover).abs() < 0.1, "cover {cover}: measured {measured}");
        }
    }
}
