//! `[[light]]`: the lights that are not shapes (point, spot, sun, sky, the paper's cloudy sky
//! and an environment map). An emissive shape is a `[[shape]]` with `emission`.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use serde::Deserialize;

use super::typed::{LightCommon, Table, Typed};
use super::{dv3, v3, Ctx, F, V3};
use crate::scene::environment::EnvironmentMap;
use crate::scene::sky::CloudySky;
use crate::scene::{Light, SceneError};

/// A light's type and its own keys.
#[derive(Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum LightKind {
    Point(Point),
    Spot(Spot),
    Sun(Sun),
    Sky(Sky),
    /// A `sky` with `zenith`.
    #[serde(rename = "cloudy sky")]
    CloudySky(Cloudy),
    Environment(Environment),
}

impl LightKind {
    /// The file an environment light reads, as written (relative to the scene file).
    pub(super) fn file(&self) -> Option<&str> {
        match self {
            LightKind::Environment(e) => Some(&e.file),
            _ => None,
        }
    }
}

impl Typed for LightKind {
    type Common = LightCommon;
    const SECTION: &'static str = "light";
    const HINT: &'static str = "; an emissive shape has `emission`";

    fn variant<'a>(kind: &'a str, has: &dyn Fn(&str) -> bool) -> &'a str {
        if kind == "sky" && has("zenith") {
            "cloudy sky"
        } else {
            kind
        }
    }

    fn type_of(variant: &'static str) -> &'static str {
        if variant == "cloudy sky" {
            "sky"
        } else {
            variant
        }
    }

    fn describe(variant: &str) -> String {
        match variant {
            "cloudy sky" => "a cloudy sky (a sky light with `zenith`)".to_string(),
            other => format!("a {other} light"),
        }
    }
}

/// Radiant intensity from a point.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Point {
    position: V3,
    intensity: V3,
}

/// A point light in a cone.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Spot {
    position: V3,
    direction: V3,
    intensity: V3,
    cone_angle: Option<F>,
    falloff_start: Option<F>,
}

/// A distant disc of directions.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Sun {
    direction: V3,
    irradiance: V3,
    angular_diameter: Option<F>,
    diffuse_source: Option<bool>,
}

/// Constant radiance from every direction.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Sky {
    radiance: V3,
    diffuse_source: Option<bool>,
}

/// CIE overcast with fBm clouds.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Cloudy {
    zenith: V3,
    clear: Option<V3>,
    cloud_cover: Option<F>,
    cloud_scale: Option<F>,
    seed: Option<u32>,
    diffuse_source: Option<bool>,
}

/// A latitude-longitude map at infinity (an HDRI).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Environment {
    file: String,
    scale: Option<F>,
    rotate: Option<F>,
    sampling: Option<String>,
    diffuse_source: Option<bool>,
}

/// A light, checked: no negative power, directions that are not zero, angles in range.
pub(super) fn light(ctx: &Ctx, dir: &Path, l: &Table<LightKind>) -> Result<Light, SceneError> {
    let span = l.span.clone();
    let non_negative = |v: V3, key: &str| -> Result<Vec3, SceneError> {
        let v = v3(v);
        if v.min_element() < 0.0 {
            ctx.err(span.clone(), format!("`{key}` must not be negative"))
        } else {
            Ok(v)
        }
    };
    match &l.of_type {
        LightKind::Point(p) => Ok(Light::Point {
            position: (dv3(p.position) - ctx.origin).as_vec3(),
            intensity: non_negative(p.intensity, "intensity")?,
        }),
        LightKind::Sun(s) => {
            let direction = v3(s.direction);
            if direction.length_squared() == 0.0 {
                return ctx.err(span, "a sun's `direction` must not be zero");
            }
            let irradiance = non_negative(s.irradiance, "irradiance")?;
            let diameter = s.angular_diameter.map_or(0.53, |d| d.0);
            if !(diameter > 0.0 && diameter < 180.0) {
                return ctx
                    .err(span, "a sun's `angular_diameter` must lie strictly between 0 and 180 degrees");
            }
            Ok(Light::sun(direction, irradiance, diameter as f64, s.diffuse_source.unwrap_or(false)))
        }
        LightKind::CloudySky(c) => {
            let zenith = non_negative(c.zenith, "zenith")?;
            let clear = match c.clear {
                Some(clear) => non_negative(clear, "clear")?,
                None => zenith,
            };
            let cover = c.cloud_cover.map_or(0.5, |c| c.0);
            if !(0.0..=1.0).contains(&cover) {
                return ctx.err(span, "`cloud_cover` must lie in [0, 1]");
            }
            let scale = c.cloud_scale.map_or(0.5, |c| c.0);
            if scale <= 0.0 {
                return ctx.err(span, "`cloud_scale` must be positive");
            }
            Ok(Light::CloudySky {
                sky: CloudySky { zenith, clear, cover, scale, seed: c.seed.unwrap_or(0) },
                diffuse_source: c.diffuse_source.unwrap_or(true),
            })
        }
        LightKind::Environment(e) => {
            let scale = e.scale.map_or(1.0, |s| s.0);
            if scale < 0.0 {
                return ctx.err(span, "an environment's `scale` must not be negative");
            }
            let path = dir.join(&e.file);
            let uniform = match e.sampling.as_deref() {
                None | Some("luminance") => false,
                Some("uniform") => true,
                Some(other) => {
                    return ctx.err(
                        span,
                        format!("unknown environment `sampling` `{other}` (expected luminance or uniform)"),
                    )
                }
            };
            let mut map = crate::scene::limits::check_input_file(&path)
                .and_then(|()| EnvironmentMap::load(&path, scale, e.rotate.map_or(0.0, |r| r.0)))
                .or_else(|e| ctx.err(span, format!("environment light: {e}")))?;
            map.uniform = uniform;
            Ok(Light::Environment {
                map: Arc::new(map),
                // An HDRI often holds a sun, whose direct light must keep its sharp shadows: its
                // light is direct unless the file says otherwise (a sky's is diffuse).
                diffuse_source: e.diffuse_source.unwrap_or(false),
            })
        }
        LightKind::Sky(s) => Ok(Light::Sky {
            radiance: non_negative(s.radiance, "radiance")?,
            diffuse_source: s.diffuse_source.unwrap_or(true),
        }),
        LightKind::Spot(s) => {
            let direction = v3(s.direction);
            if direction.length_squared() == 0.0 {
                return ctx.err(span, "a spot light's `direction` must not be zero");
            }
            let cone = s.cone_angle.map_or(30.0, |a| a.0);
            if !(cone > 0.0 && cone <= 180.0) {
                return ctx.err(span, "a spot light's `cone_angle` must lie in (0, 180] degrees");
            }
            let start = s.falloff_start.map_or(0.75 * cone, |a| a.0);
            if !(0.0..=cone).contains(&start) {
                return ctx.err(span, "`falloff_start` must lie between 0 and `cone_angle` degrees");
            }
            Ok(Light::Spot {
                position: (dv3(s.position) - ctx.origin).as_vec3(),
                direction: direction.normalize(),
                intensity: non_negative(s.intensity, "intensity")?,
                cos_total: cone.to_radians().cos(),
                cos_falloff_start: start.to_radians().cos(),
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::tests::{error_line, parse_str, MINIMAL};

    #[test]
    fn sun_keeps_its_tiny_solid_angle() {
        let text =
            format!("{MINIMAL}[[light]]\ntype = \"sun\"\ndirection = [0, 1, 0]\nirradiance = [1, 1, 1]\n");
        let s = parse_str(&text).expect("parses");
        let Light::Sun { one_minus_cos, radiance, .. } = &s.lights[0] else { panic!("sun") };
        let half = (0.53f64 / 2.0).to_radians();
        let expected = 1.0 - half.cos();
        assert!(((*one_minus_cos as f64) - expected).abs() < 1e-6 * expected);
        // Radiance times solid angle gives back the irradiance.
        let e = radiance.x as f64 * 2.0 * std::f64::consts::PI * (*one_minus_cos as f64);
        assert!((e - 1.0).abs() < 1e-5, "{e}");
    }

    #[test]
    fn a_sky_with_zenith_is_cloudy_and_takes_the_cloudy_keys() {
        let sky = format!("{MINIMAL}[[light]]\ntype = \"sky\"\n");
        let s = parse_str(&format!("{sky}zenith = [1, 1, 1]\ncloud_cover = 0.3\n")).expect("parses");
        assert!(matches!(s.lights[0], Light::CloudySky { diffuse_source: true, .. }), "{:?}", s.lights);
        let (line, msg) = error_line(&format!("{sky}zenith = [1, 1, 1]\nradiance = [1, 1, 1]\n"));
        assert_eq!(line, Some(4), "{msg}");
        assert!(msg.contains("cloudy sky") && msg.contains("`radiance` (only sky lights do)"), "{msg}");
        let (_, msg) = error_line(&format!("{sky}radiance = [1, 1, 1]\nclear = [1, 1, 1]\n"));
        assert!(msg.contains("a sky light does not take `clear` (only cloudy sky lights do)"), "{msg}");
        let (_, msg) =
            error_line(&format!("{MINIMAL}[[light]]\ntype = \"cloudy sky\"\nzenith = [1, 1, 1]\n"));
        assert!(
            msg.contains("unknown light type `cloudy sky` (expected point, spot, sun, sky or environment;"),
            "{msg}"
        );
    }
}
