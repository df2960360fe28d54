//! Light path expressions (LPEs): OSL's regular expressions over the events of a
//! camera path, compiled into ONE deterministic automaton that the renderer steps
//! once per path vertex (one table lookup) to learn which AOVs a path feeds.
//!
//! # Alphabet
//! Every path vertex is one event `(type, scattering, label)`:
//!
//! | letter | [`Type`]        | produced by                                                  |
//! |--------|-----------------|--------------------------------------------------------------|
//! | `C`    | `Camera`        | the first vertex                                             |
//! | `R`    | `Reflection`    | a reflection at a surface                                    |
//! | `T`    | `Transmission`  | a transmission through a surface                             |
//! | `L`    | `Light`         | any sampled emitter: emissive surface, point, spot, sun, sky, environment |
//! | `O`    | `Object`        | an emitter flagged "diffuse source" (stands for diffusely reflected surroundings) |
//! | `B`    | `Background`    | the path left the scene and found nothing                   |
//! | `V`    | `Volume`        | volume scattering (parsed; never produced today)            |
//! | `A`    | `Albedo`        | the albedo of a vertex's lobes of the scattering before it (Arnold's `A`) |
//!
//! Scattering ([`Scatter`]): `D` diffuse, `G` glossy, `S` singular (delta), and `x` for
//! none (the scattering of `C`, `L`, `O`, `B`, `A` events; `R` and `T` always scatter, `V` may
//! do either). Other pairs (a diffuse `L`, an `R` without scattering) are not events: they
//! send every state to the dead one. The label is none (id 0) or one of the light-group
//! names the scene defines ([`Labels`]).
//!
//! # Grammar
//! Whitespace is ignored (except inside `'labels'`, and see the shorthand below).
//! * `<t s l>` — one event; each position is a letter, `.` (any), a set `[..]` or a
//!   negated set `[^..]`. `t` takes `C R T L O B V A`, `s` takes `D G S x`, `l` takes
//!   `'name'` or `x` (no label). Missing trailing positions mean any: `<RD>` = `<RD.>`.
//!   A label written early fills the skipped positions with `.`: `<L'key'>` = `<L.'key'>`.
//! * A bare letter outside `<>`: a type letter means that type with any scattering and
//!   any label (`R` = `<R..>`); `D G S` mean any type with that scattering (`D` = `<.D.>`).
//! * `'name'` outside `<>`: any event carrying that label.
//! * `[..]` / `[^..]` outside `<>`: the union / complement of the bare items inside
//!   (letters, `.`, labels): `[GS]` = any glossy or singular event, `[^D]` = any event
//!   that is not diffuse, `[LO]` = any light or diffuse-source event.
//! * Label shorthand: a `'name'` written directly (no space) after a bare letter, `.`,
//!   `[..]` or `<..>` restricts that ONE event to the label: `L'key'` = `<L.'key'>`.
//!   OSL reads `L'key'` as two events (an `L`, then an event labelled `key`); since our
//!   events carry at most one label that reading can never match, so we read it as one.
//! * `.` any event; postfix `*`, `+`, `?`, `{n}`, `{n,}`, `{n,m}` (counts up to 64);
//!   concatenation by juxtaposition; `|` alternation (lowest precedence); `( )` grouping.
//!
//! Expressions need not start with `C`. Names a scene does not define are accepted and
//! simply never match (so `[^'nope']` matches everything).
//!
//! # Differences from OSL's parser (`lpeparse.cpp`)
//! * `|` has the usual lowest precedence: `AB|CD` = `(AB)|(CD)`. OSL's parser binds `|`
//!   to the single neighbouring items, reading `AB|CD` as `A(B|C)D`. Write the
//!   alternatives in parentheses, `(AB)|(CD)`, to mean the same thing in both.
//! * `?` is accepted (OSL has no `?`); `s` (OSL's "straight") and user-defined event
//!   or scattering letters are not part of this alphabet and are errors.
//! * Sets hold single-event items only (OSL allows sub-expressions in `[..]`); a negated
//!   bare set mixing types and scatterings is the complement of the union (`[^LD]` =
//!   neither light nor diffuse), where OSL warns and negates one position only.
//! * Only an `A` written out (a letter, in `<>` or in a set) matches an albedo event: `.`,
//!   negated sets and scattering letters leave it out, so `C.*` never holds an albedo.
//! * An event has at most one label (`<RD'a''b'>` is an error); an unlabelled event
//!   matches `[^'coat']` and `x` in the label position (OSL needs a label there).
//!
//! # Use
//! ```ignore
//! let aovs = Aovs::compile(&[("direct", "C[GS]*DL"), ("key", "C.*L'key'")], &["key"])?;
//! let mut s = aovs.start();
//! for &(ty, sc, label) in path { s = aovs.next(s, aovs.symbol(ty, sc, label)); if aovs.is_dead(s) { break } }
//! let mask = aovs.accepts(s); // bit i set: add the contribution to AOV i
//! ```

mod automaton;
mod builtin;
mod parse;

pub use builtin::{builtin, BUILTINS};

use std::fmt;

/// Most expressions one [`Aovs`] can hold (one bit each of [`Aovs::accepts`]).
pub const MAX_EXPRS: usize = 64;

/// The type of a path event.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Type {
    /// `C`: the camera.
    Camera,
    /// `R`: reflection at a surface.
    Reflection,
    /// `T`: transmission through a surface.
    Transmission,
    /// `L`: any emitter the renderer samples.
    Light,
    /// `O`: an emitter flagged as a diffuse source.
    Object,
    /// `B`: the path left the scene with nothing there.
    Background,
    /// `V`: volume scattering (never produced today).
    Volume,
    /// `A`: the albedo of the lobes of the scattering event before it. Only an `A` (or `<A>`)
    /// written out matches one: `.` and negated sets do not, so `C.*` never holds an albedo.
    Albedo,
}

impl Type {
    /// Every type, in symbol order.
    pub const ALL: [Type; 8] = {
        use Type::*;
        [Camera, Reflection, Transmission, Light, Object, Background, Volume, Albedo]
    };

    /// The letter that names this type in expressions.
    pub fn letter(self) -> char {
        char::from(b"CRTLOBVA"[self as usize])
    }

    fn from_letter(c: char) -> Option<Type> {
        Type::ALL.into_iter().find(|t| t.letter() == c)
    }
}

/// The scattering of a path event.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Scatter {
    /// `x`: no scattering (camera, light, diffuse-source and background events).
    None,
    /// `D`: diffuse.
    Diffuse,
    /// `G`: glossy.
    Glossy,
    /// `S`: singular (delta).
    Singular,
}

impl Scatter {
    /// Every scattering, in symbol order.
    pub const ALL: [Scatter; 4] = {
        use Scatter::*;
        [None, Diffuse, Glossy, Singular]
    };

    /// The letter that names this scattering in expressions.
    pub fn letter(self) -> char {
        char::from(b"xDGS"[self as usize])
    }

    fn from_letter(c: char) -> Option<Scatter> {
        Scatter::ALL.into_iter().find(|s| s.letter() == c)
    }
}

/// A malformed expression: where it went wrong and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LpeError {
    /// 0-based char (not byte) offset in the expression; `Display` shows it 1-based.
    pub position: usize,
    /// What is wrong there.
    pub message: String,
}

impl LpeError {
    fn new(position: usize, message: impl Into<String>) -> LpeError {
        LpeError { position, message: message.into() }
    }
}

impl fmt::Display for LpeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "column {}: {}", self.position + 1, self.message)
    }
}

impl std::error::Error for LpeError {}

/// The scene's light-group names and their small ids (id 0 = no label).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Labels {
    names: Vec<String>,
}

impl Labels {
    fn new(names: &[&str]) -> Labels {
        Labels { names: names.iter().map(|s| s.to_string()).collect() }
    }

    /// The id of `name` (the first one if repeated), or `None` if the scene lacks it.
    pub fn id(&self, name: &str) -> Option<u16> {
        let i = self.names.iter().position(|n| n == name)?;
        u16::try_from(i + 1).ok()
    }

    /// The name of label `id`, or `None` for 0 (no label) and unknown ids.
    pub fn name(&self, id: u16) -> Option<&str> {
        let i = usize::from(id).checked_sub(1)?;
        self.names.get(i).map(String::as_str)
    }

    /// Number of names; their ids are `1..=len`.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True if the scene defines no labels.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }
}

/// An automaton state: where a path prefix has got to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct State(u16);

impl State {
    /// The absorbing state of prefixes that no expression can match any more.
    pub const DEAD: State = State(0);

    /// The state number, `0..Aovs::states()`, for indexing per-state data.
    pub fn index(self) -> usize {
        usize::from(self.0)
    }
}

/// A precomputed event class, as fed to [`Aovs::next`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Symbol(u32);

/// A compiled set of named expressions: one minimal DFA over all of them.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Aovs {
    names: Vec<String>,
    labels: Labels,
    dfa: automaton::Dfa,
}

impl Aovs {
    /// Compiles named expressions into one deterministic, minimised automaton.
    ///
    /// `labels` are the light-group names the scene defines; label id `i + 1` is
    /// `labels[i]`. Errors carry the index of the offending expression; errors about
    /// the set as a whole (more than [`MAX_EXPRS`] expressions: index `MAX_EXPRS`; too
    /// many labels or states: index `exprs.len()`) have position 0.
    pub fn compile(exprs: &[(&str, &str)], labels: &[&str]) -> Result<Aovs, (usize, LpeError)> {
        if exprs.len() > MAX_EXPRS {
            let msg = format!("at most {MAX_EXPRS} expressions can be compiled together");
            return Err((MAX_EXPRS, LpeError::new(0, msg)));
        }
        if labels.len() >= usize::from(u16::MAX) {
            let msg = format!("at most {} labels", u16::MAX - 1);
            return Err((exprs.len(), LpeError::new(0, msg)));
        }
        let trees = exprs
            .iter()
            .enumerate()
            .map(|(i, (_, text))| parse::parse(text).map_err(|e| (i, e)))
            .collect::<Result<Vec<_>, _>>()?;
        let labels = Labels::new(labels);
        let dfa = automaton::build(&trees, &labels).map_err(|e| (exprs.len(), e))?;
        let names = exprs.iter().map(|(n, _)| n.to_string()).collect();
        Ok(Aovs { names, labels, dfa })
    }

    /// The state before any event; the renderer then feeds the camera event.
    pub fn start(&self) -> State {
        State(self.dfa.start)
    }

    /// The symbol of an event; unknown label ids count as no label, impossible pairs kill.
    #[inline]
    pub fn symbol(&self, ty: Type, scatter: Scatter, label: u16) -> Symbol {
        let nl1 = self.labels.len() + 1;
        let label = usize::from(label);
        let label = if label < nl1 { label } else { 0 };
        Symbol(self.dfa.classes[(ty as usize * 4 + scatter as usize) * nl1 + label])
    }

    /// The state after feeding `sym` in state `s` (the dead state absorbs).
    #[inline]
    pub fn next(&self, s: State, sym: Symbol) -> State {
        State(self.dfa.table[s.index() * self.dfa.nclasses + sym.0 as usize])
    }

    /// True if no expression can match any continuation of the path.
    #[inline]
    pub fn is_dead(&self, s: State) -> bool {
        s == State::DEAD
    }

    /// The expressions some path ending in `sym` matches: bit `i` set when a state's successor
    /// on `sym` accepts expression `i`.
    pub fn accepted_after(&self, sym: Symbol) -> u64 {
        (0..self.states()).fold(0, |m, s| m | self.accepts(self.next(State(s as u16), sym)))
    }

    /// Bit `i` is set if expression `i` matches the path that led to `s`.
    #[inline]
    pub fn accepts(&self, s: State) -> u64 {
        self.dfa.accept[s.index()]
    }

    /// Number of expressions.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// True if no expressions were compiled.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The name of expression `i`.
    pub fn name(&self, i: usize) -> &str {
        &self.names[i]
    }

    /// Number of automaton states, the dead state included.
    pub fn states(&self) -> usize {
        self.dfa.accept.len()
    }

    /// Number of distinct symbols (event classes): the width of the transition table.
    pub fn symbols(&self) -> usize {
        self.dfa.nclasses
    }

    /// The scene labels this set was compiled against.
    pub fn labels(&self) -> &Labels {
        &self.labels
    }
}

#[cfg(test)]
pub(crate) mod testing {
    use super::*;

    /// One event as the tests write it: `C`, `RD`, `L'key'`, `TG'a'`.
    pub(crate) type Ev = (Type, Scatter, u16);

    /// Parses a space-separated path such as `"C RD L'key'"` (unknown labels = id 0).
    pub(crate) fn path(text: &str, labels: &Labels) -> Vec<Ev> {
        let ev = |tok: &str| {
            let mut cs = tok.chars();
            let ty = Type::from_letter(cs.next().unwrap()).unwrap();
            let rest: String = cs.collect();
            let (sc, label) = rest.split_once('\'').unwrap_or((&rest, ""));
            let sc = sc.chars().next().map_or(Scatter::None, |c| Scatter::from_letter(c).unwrap());
            (ty, sc, labels.id(label.trim_end_matches('\'')).unwrap_or(0))
        };
        text.split_whitespace().map(ev).collect()
    }

    /// Runs the automaton over a whole path and returns the accept mask.
    pub(crate) fn run(aovs: &Aovs, path: &[Ev]) -> u64 {
        let mut s = aovs.start();
        for &(t, sc, l) in path {
            s = aovs.next(s, aovs.symbol(t, sc, l));
        }
        aovs.accepts(s)
    }

    #[test]
    fn api_basics() {
        let aovs = Aovs::compile(&[("d", "C[GS]*DL"), ("k", "C.*L'key'")], &["fill", "key"]).unwrap();
        assert_eq!((aovs.len(), aovs.name(1)), (2, "k"));
        assert_eq!(aovs.labels().id("key"), Some(2));
        assert_eq!(aovs.labels().name(1), Some("fill"));
        assert_eq!(run(&aovs, &path("C RD L'key'", aovs.labels())), 0b11);
        assert_eq!(run(&aovs, &path("C RD L'fill'", aovs.labels())), 0b01);
        assert_eq!(run(&aovs, &path("C RD RG L'key'", aovs.labels())), 0b10);
        assert_eq!(run(&aovs, &path("C RG RD L'key'", aovs.labels())), 0b11);
        let s = aovs.next(aovs.start(), aovs.symbol(Type::Light, Scatter::None, 0));
        assert!(aovs.is_dead(s) && aovs.accepts(s) == 0);
        // Out-of-range label ids count as "no label".
        assert_eq!(aovs.symbol(Type::Light, Scatter::None, 999), aovs.symbol(Type::Light, Scatter::None, 0));
        let many: Vec<(&str, &str)> = vec![("x", "C"); MAX_EXPRS + 1];
        assert_eq!(Aovs::compile(&many, &[]).unwrap_err().0, MAX_EXPRS);
        let err = Aovs::compile(&[("ok", "CL"), ("bad", "CQ")], &[]).unwrap_err();
        assert_eq!(err.0, 1);
        assert_eq!(err.1.to_string(), "column 2: unknown event letter 'Q'");
    }
}
