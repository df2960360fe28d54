//! The light path expressions a render evaluates ([`crate::lpe`]): the paper's four components
//! first, as the built-in expressions `emitted`, `direct`, `caustic` and `indirect`, then the
//! render's AOVs, compiled once into one automaton that each path steps at its vertices. A
//! contribution's bit mask says which expressions its path matches; the components partition
//! every path, so exactly one of the first four bits is set, and bit `4 + i` is AOV `i`.
//!
//! The events the integrator produces: `C` at the eye; at each scattering vertex `R` (the
//! sampled direction leaves on the side the path came from) or `T`, with the lobe's tag as the
//! scattering (diffuse `D`, a glossy lobe `G`, a delta lobe `S`); `L` for light from an emitter
//! the light list holds, `O` for one flagged as a diffuse source. Next-event estimation only
//! ever reflects.

use crate::component::Component;
use crate::lpe::{Aovs, Scatter, State, Symbol, Type, BUILTINS, MAX_EXPRS};
use crate::scene::Aov;

use super::bsdf::Lobe;
use super::lights::Lights;

/// The component expressions, compiled, with the symbols of the events a path produces.
#[derive(Clone, Debug)]
pub struct PathExprs {
    aovs: Aovs,
    /// The state after the camera event.
    start: State,
    /// The scattering events: [reflection, transmission] x [diffuse, glossy, singular].
    scatter: [[Symbol; 3]; 2],
    /// Each light's event by its index in the light list: `L`, or `O` for a diffuse source.
    light: Vec<Symbol>,
    /// Emission from a surface the light list lacks.
    unlisted: Symbol,
    /// The albedo event `A`, and the AOVs a path ending in one can match (none: no albedo is
    /// looked at).
    albedo: Symbol,
    albedo_aovs: u64,
}

/// The mask bits of the paper's components, in [`Component::ALL`] order.
pub const COMPONENT_BITS: u64 = (1 << Component::ALL.len()) - 1;

/// The most AOVs a render computes (beside the components, one bit each of a mask).
pub const MAX_AOVS: usize = MAX_EXPRS - Component::ALL.len();

impl PathExprs {
    /// The paper's four components as expressions, for a scene with these lights: no AOVs.
    pub fn new(lights: &Lights) -> PathExprs {
        // The built-ins are constants of the program, compiled by a unit test too.
        PathExprs::with_aovs(lights, &[], &[]).expect("the built-in expressions compile")
    }

    /// The components and `aovs` (checked when they were read, at most [`MAX_AOVS`]), in a
    /// scene of light groups `groups` (labels `'name'`; light `i` is in group
    /// `lights.group[i]`); an error only where their automaton grows past its limit.
    pub fn with_aovs(lights: &Lights, aovs: &[Aov], groups: &[String]) -> Result<PathExprs, String> {
        let exprs: Vec<(&str, &str)> = BUILTINS[..Component::ALL.len()]
            .iter()
            .copied()
            .chain(aovs.iter().map(|a| (a.name.as_str(), a.lpe.as_str())))
            .collect();
        // Only an AOV can name a group: without one, no labels (a scene of more groups than an
        // automaton can label renders its components all the same; unknown labels are none).
        let labels: Vec<&str> = match aovs.is_empty() {
            true => Vec::new(),
            false => groups.iter().map(String::as_str).collect(),
        };
        let aovs = Aovs::compile(&exprs, &labels).map_err(|(i, e)| match exprs.get(i) {
            Some((name, expr)) => format!("AOV `{name}`: `{expr}`: {e}"),
            None => format!("the AOVs' expressions together: {e}"),
        })?;
        let scatter =
            |ty| [Scatter::Diffuse, Scatter::Glossy, Scatter::Singular].map(|s| aovs.symbol(ty, s, 0));
        let emits = |source: bool, group: u16| {
            let ty = if source { Type::Object } else { Type::Light };
            aovs.symbol(ty, Scatter::None, group)
        };
        let group = |i: usize| lights.group.get(i).copied().unwrap_or(0);
        let albedo = aovs.symbol(Type::Albedo, Scatter::None, 0);
        Ok(PathExprs {
            albedo,
            albedo_aovs: aovs.accepted_after(albedo) & !COMPONENT_BITS,
            start: aovs.next(aovs.start(), aovs.symbol(Type::Camera, Scatter::None, 0)),
            scatter: [scatter(Type::Reflection), scatter(Type::Transmission)],
            light: lights.diffuse_source.iter().enumerate().map(|(i, &s)| emits(s, group(i))).collect(),
            unlisted: emits(false, 0),
            aovs,
        })
    }

    /// The AOVs beside the components.
    pub fn aovs(&self) -> usize {
        self.aovs.len() - Component::ALL.len()
    }

    /// The state of a path that has left the eye.
    #[inline(always)]
    pub fn start(&self) -> State {
        self.start
    }

    /// The state after a vertex of `lobe`'s kind, its direction `transmitted` through the
    /// surface or not.
    #[inline(always)]
    pub fn scatter(&self, s: State, lobe: Lobe, transmitted: bool) -> State {
        let k = match lobe {
            Lobe::Diffuse => 0,
            Lobe::Specular => 1,
            Lobe::Delta => 2,
        };
        self.aovs.next(s, self.scatter[transmitted as usize][k])
    }

    /// Whether an AOV holds albedos (its expression ends in `A`).
    #[inline(always)]
    pub fn has_albedo(&self) -> bool {
        self.albedo_aovs != 0
    }

    /// The AOVs that take the albedo of a vertex's `lobe` kind, the path having reached the
    /// vertex in state `s`: the albedo event after that kind's reflection (`R`), whatever side
    /// the lobe scatters to (an albedo is what a surface reflects).
    #[inline(always)]
    pub fn albedo(&self, s: State, lobe: Lobe) -> u64 {
        self.aovs.accepts(self.aovs.next(self.scatter(s, lobe, false), self.albedo)) & self.albedo_aovs
    }

    /// The expressions matched by light from `light` (its index in the light list; `None`, a
    /// surface the list lacks) reaching a path in state `s`.
    #[inline(always)]
    pub fn light(&self, s: State, light: Option<u32>) -> u64 {
        let sym = light.and_then(|i| self.light.get(i as usize)).copied().unwrap_or(self.unlisted);
        self.aovs.accepts(self.aovs.next(s, sym))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_built_ins_are_the_components_in_order() {
        for (c, (name, _)) in Component::ALL.iter().zip(BUILTINS) {
            assert_eq!(c.name(), *name);
        }
    }

    /// Every path of up to four vertices ends in exactly one component, the one the paper's
    /// classification gives: Emitted with no D vertex, Direct after one D and nothing
    /// specular after it, Caustic after one D and something specular after it, Indirect after
    /// two D (or a diffuse source's light after one).
    #[test]
    fn each_path_matches_its_component() {
        let mut lights = Lights::default();
        lights.diffuse_source = vec![false, true];
        let exprs = PathExprs::new(&lights);
        let lobes = [Lobe::Diffuse, Lobe::Specular, Lobe::Delta];
        let mut checked = 0;
        for len in 0..5u32 {
            for code in 0..6u32.pow(len) {
                let (mut s, mut diffuse, mut specular_after) = (exprs.start(), 0, false);
                let mut c = code;
                for _ in 0..len {
                    let (lobe, transmitted) = (lobes[(c % 3) as usize], c % 6 >= 3);
                    c /= 6;
                    s = exprs.scatter(s, lobe, transmitted);
                    if lobe == Lobe::Diffuse {
                        diffuse += 1;
                    } else if diffuse == 1 {
                        specular_after = true;
                    }
                }
                for (light, source) in [(Some(0), false), (Some(1), true), (None, false)] {
                    let want = match diffuse {
                        0 => Component::Emitted,
                        _ if source => Component::Indirect,
                        1 if specular_after => Component::Caustic,
                        1 => Component::Direct,
                        _ => Component::Indirect,
                    };
                    let mask = exprs.light(s, light);
                    assert_eq!(
                        mask & COMPONENT_BITS,
                        1 << want.index(),
                        "path {code} of {len}, light {light:?}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 4000);
    }
}
