//! Named built-in expressions.

/// Built-in `(name, expression)` pairs.
///
/// The first four are the paper's components, which partition every camera path ending at
/// an emitter (its "S" is our `G` or `S`, its "D" our `D`; `R` and `T` are both allowed).
/// `indirect` keeps its alternatives in parentheses so OSL's parser reads it the same.
/// The others are Arnold's built-in LPE AOVs (Arnold User Guide, "Light Path Expression
/// AOVs"), by Arnold's names, but for `direct` and `indirect`, whose names the paper's
/// components have: `arnold_direct`, `arnold_indirect`. Arnold has no `G`, its `S` is every
/// non-diffuse lobe, so its `[DSV]` is our `[DGSV]`. Arnold's emissive meshes are `O` events and
/// go to its indirect; ours are lights (`L`), so a diffuse bounce onto one is `arnold_direct`.
/// Arnold's `albedo` (`C[DSV]A`) is `arnold_albedo`, `C[DGSV]A` (the film's `albedo` layer
/// is the guide buffers'): the albedo of the first surface's lobes.
pub const BUILTINS: &[(&str, &str)] = &[
    ("emitted", "C[GS]*[LO]"),
    ("direct", "C[GS]*DL"),
    ("caustic", "C[GS]*D[GS]+L"),
    ("indirect", "C[GS]*D[GS]*((D.*[LO])|O)"),
    ("arnold_direct", "C[DGSV]L"),
    ("arnold_indirect", "C[DGSV][DGSVOB].*"),
    ("diffuse_direct", "C<RD>L"),
    ("diffuse_indirect", "C<RD>[DGSVOB].*"),
    ("emission", "C[LO]"),
    ("arnold_albedo", "C[DGSV]A"),
];

/// The built-in expression called `name`, if there is one.
pub fn builtin(name: &str) -> Option<&'static str> {
    BUILTINS.iter().find(|(n, _)| *n == name).map(|(_, e)| *e)
}

#[cfg(test)]
mod tests {
    use super::super::testing::{path, run};
    use super::super::{Aovs, Scatter, Type};
    use super::*;

    #[test]
    fn builtins_compile() {
        for (name, expr) in BUILTINS {
            assert!(Aovs::compile(&[(name, expr)], &[]).is_ok(), "{name}");
        }
        assert_eq!(builtin("direct"), Some("C[GS]*DL"));
        assert_eq!(builtin("arnold_albedo"), Some("C[DGSV]A"));
        assert_eq!(builtin("nonesuch"), None);
    }

    /// Albedo events: Arnold's `albedo` takes the first surface's, of any lobe; only an `A`
    /// written out matches one, so expressions of light (`C.*`, `C[^L]`) never hold an albedo.
    #[test]
    fn albedo_events_match_only_where_named() {
        let exprs =
            [("arnold_albedo", "C[DGSV]A"), ("all", "C.*"), ("not_light", "C[^L]"), ("diffuse", "C<RD>A")];
        assert_eq!(builtin("arnold_albedo"), Some(exprs[0].1));
        let aovs = Aovs::compile(&exprs, &[]).unwrap();
        let at = |p: &str| run(&aovs, &path(p, aovs.labels()));
        assert_eq!(at("C RD A"), 0b1001);
        assert_eq!(at("C RS A"), 0b0001);
        assert_eq!(at("C RD RD A"), 0);
        assert_eq!(at("C RG"), 0b0110);
        assert_eq!(at("C RG L"), 0b0010);
    }

    /// Every `C (R|T)(D|G|S) ... (L|O)` path of up to 7 events is in exactly one component.
    #[test]
    fn components_partition_paths() {
        let aovs = Aovs::compile(&BUILTINS[..4], &[]).unwrap();
        let mut checked = 0;
        for bounces in 0..=5u32 {
            for code in 0..6usize.pow(bounces) {
                let mut p = vec![(Type::Camera, Scatter::None)];
                for b in 0..bounces {
                    let digit = code / 6usize.pow(b) % 6;
                    p.push((Type::ALL[1 + digit / 3], Scatter::ALL[1 + digit % 3]));
                }
                for end in [Type::Light, Type::Object] {
                    p.push((end, Scatter::None));
                    let s = p.iter().fold(aovs.start(), |s, &(t, sc)| aovs.next(s, aovs.symbol(t, sc, 0)));
                    assert_eq!(aovs.accepts(s).count_ones(), 1, "{p:?}: {:b}", aovs.accepts(s));
                    p.pop();
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, 2 * (1 + 6 + 36 + 216 + 1296 + 7776));
    }

    #[test]
    fn components_examples() {
        let aovs = Aovs::compile(BUILTINS, &[]).unwrap();
        let names = |p: &str| {
            let m = run(&aovs, &path(p, aovs.labels()));
            let hit: Vec<&str> = (0..aovs.len()).filter(|&i| m >> i & 1 == 1).map(|i| aovs.name(i)).collect();
            hit.join(" ")
        };
        assert_eq!(names("C RS L"), "emitted arnold_direct");
        assert_eq!(names("C L"), "emitted emission");
        assert_eq!(names("C O"), "emitted emission");
        assert_eq!(names("C RD L"), "direct arnold_direct diffuse_direct");
        assert_eq!(names("C TG RD L"), "direct arnold_indirect");
        assert_eq!(names("C RD TS L"), "caustic arnold_indirect diffuse_indirect");
        assert_eq!(names("C RD O"), "indirect arnold_indirect diffuse_indirect");
        assert_eq!(names("C TD RD L"), "indirect arnold_indirect");
        assert_eq!(names("C RG L"), "emitted arnold_direct");
        assert_eq!(names("C B"), "");
    }

    #[test]
    fn state_counts() {
        let show = |what: &str, a: &Aovs| println!("{what}: {} states, {} symbols", a.states(), a.symbols());
        for (name, expr) in BUILTINS {
            show(name, &Aovs::compile(&[(name, expr)], &[]).unwrap());
        }
        let four = Aovs::compile(&BUILTINS[..4], &[]).unwrap();
        let all = Aovs::compile(BUILTINS, &["key", "fill"]).unwrap();
        show("the paper's four together", &four);
        show("all ten together", &all);
        // Minimal DFAs are unique, so these only move if the languages change.
        assert_eq!((four.states(), all.states()), (11, 29));
    }
}
