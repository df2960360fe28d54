//! A scene file's `[filter]` section as a filter setting. The scene keeps the section as written
//! (it knows nothing of filters); the kernel names and weights, targets and edge stops are checked
//! here, with the same rules as the command line's flags.

use super::{EdgeStops, Method, Setting, Target};
use crate::scene::{FilterSection, KernelSpec, Scene, SceneError};

impl Setting {
    /// The setting a `[filter]` section asks for, or what is wrong with it.
    pub fn from_section(section: &FilterSection) -> Result<Setting, String> {
        let kernel = match &section.kernel {
            KernelSpec::Name(name) => Method::parse(name),
            KernelSpec::Weights(weights) => Method::custom(weights.clone()),
        }?;
        let target = match section.target.as_deref() {
            None => Target::Indirect,
            Some(name) => Target::from_name(name).ok_or_else(|| {
                format!("unknown filter target `{name}` (indirect, image, components, none or an AOV's name)")
            })?,
        };
        let stops = EdgeStops {
            object: section.edge_aware.unwrap_or(false),
            normal_degrees: section.edge_normal,
            depth_relative: section.edge_depth,
            pure: section.edge_pure.unwrap_or(false),
        };
        stops.check()?;
        Ok(Setting { method: Some(kernel), target, stops })
    }

    /// The setting of a scene's `[filter]` section (no filter without one); a bad section is an
    /// error at the section's line of the scene file.
    pub fn of_scene(scene: &Scene) -> Result<Setting, SceneError> {
        match &scene.filter {
            None => Ok(Setting::default()),
            Some(section) => Setting::from_section(section)
                .map_err(|e| SceneError::new(&scene.path, Some(section.line), e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::file::tests::{parse_str, MINIMAL};

    /// The scene's setting, or the line and message of the first error, the scene's or the section's.
    fn setting(text: &str) -> Result<Setting, (Option<usize>, String)> {
        parse_str(text).and_then(|s| Setting::of_scene(&s)).map_err(|e| (e.line, e.message))
    }

    #[test]
    fn filter_section_by_name_or_weights_and_its_errors() {
        let s = setting(&format!("{MINIMAL}[filter]\nkernel = \"median3\"\ntarget = \"image\"\n"))
            .expect("parses");
        assert_eq!(s.method, Some(Method::Median3));
        assert_eq!(s.target, Target::Image);
        let s =
            setting(&format!("{MINIMAL}[filter]\nkernel = [0, 1, 0, 1, 4, 1, 0, 1, 0]\nedge_normal = 30\n"))
                .expect("parses");
        assert_eq!((s.target, s.stops.normal_degrees), (Target::Indirect, Some(30.0)));
        assert_eq!(setting(MINIMAL).expect("parses"), Setting::default());
        let s =
            setting(&format!("{MINIMAL}[filter]\nkernel = \"atrous:sigma_l=8\"\ntarget = \"components\"\n"))
                .expect("parses");
        assert_eq!(
            s.method,
            Some(Method::Atrous(crate::filter::Atrous { sigma_l: 8.0, ..Default::default() }))
        );
        assert_eq!(s.target, Target::Components);
        for (extra, needle) in [
            ("kernel = \"gauss\"\n", "gauss"),
            ("kernel = [1, 2, 3, 4]\n", "odd square"),
            ("kernel = \"box3\"\ntarget = \"all-of-it\"\n", "all-of-it"),
            ("kernel = \"box3\"\nedge_normal = 0\n", "normal"),
            ("kernel = \"box3\"\nradius = 2\n", "radius"),
            ("kernel = \"atrous:passes=0\"\n", "passes"),
        ] {
            let (line, msg) = setting(&format!("{MINIMAL}[filter]\n{extra}")).expect_err("must fail");
            assert!(line.is_some_and(|l| l >= 4), "{extra}: {line:?} {msg}");
            assert!(msg.contains(needle), "{extra}: {msg}");
        }
    }
}

/// The command line's filter flags, laid over a base setting (a scene's `[filter]`, or none):
/// what `render`, `filter`, `merge` and `info` are asked for.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// `--filter`: a method by name (or weights).
    pub method: Option<String>,
    /// `--denoise`: the best setting measured ([`Setting::denoise`]), whatever the base.
    pub denoise: bool,
    /// `--filter-target`.
    pub target: Option<Target>,
    /// `--edge-aware`, `--edge-normal`, `--edge-depth`, `--edge-pure`.
    pub object: bool,
    pub normal_degrees: Option<f32>,
    pub depth_relative: Option<f32>,
    pub pure: bool,
}

impl Overrides {
    /// The setting to use: these over `base`. A method named here applies to its default
    /// target (indirect), not to the base's; the edge stops add to the base's.
    pub fn over(&self, base: &Setting) -> Result<Setting, String> {
        if self.denoise {
            return Ok(Setting::denoise());
        }
        let method = match self.method.as_deref() {
            Some(name) => Some(Method::parse(name)?),
            None => base.method.clone(),
        };
        let target = match (self.target, &self.method) {
            (Some(t), _) => t,
            (None, Some(_)) => Target::Indirect,
            (None, None) => base.target,
        };
        if target != Target::None && method.is_none() {
            return Err("--filter-target needs --filter".into());
        }
        let stops = EdgeStops {
            object: self.object || base.stops.object,
            normal_degrees: self.normal_degrees.or(base.stops.normal_degrees),
            depth_relative: self.depth_relative.or(base.stops.depth_relative),
            pure: self.pure || base.stops.pure,
        };
        stops.check().map_err(|e| format!("--edge-normal/--edge-depth: {e}"))?;
        Ok(Setting { method, target, stops })
    }
}
