//! Expression text -> [`Node`] tree whose leaves are event predicates ([`Pred`]).

use super::{LpeError, Scatter, Type};

/// Deepest `( )` nesting accepted (keeps recursion bounded).
const MAX_DEPTH: usize = 64;
/// Largest repeat count in `{n,m}`.
const MAX_COUNT: u32 = 64;
/// Most event leaves an expression may have once repeats are expanded.
const MAX_SIZE: usize = 10_000;

/// A predicate over one event `(type, scattering, label)`.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Pred {
    Any,
    /// Bit `Type as u8` set for each allowed type.
    Types(u8),
    /// Bit `Scatter as u8` set for each allowed scattering.
    Scatters(u8),
    /// The event carries exactly this label (`None`: no label).
    Label(Option<String>),
    And(Vec<Pred>),
    Or(Vec<Pred>),
    Not(Box<Pred>),
}

impl Pred {
    /// Whether the predicate allows type `ty` by naming it (not by `.` or a negation).
    fn names(&self, ty: Type) -> bool {
        match self {
            Pred::Types(m) => m & (1 << ty as u8) != 0,
            Pred::And(v) | Pred::Or(v) => v.iter().any(|p| p.names(ty)),
            Pred::Any | Pred::Scatters(_) | Pred::Label(_) | Pred::Not(_) => false,
        }
    }

    /// Whether the event `(ty, sc, label name)` satisfies the predicate.
    pub(crate) fn matches(&self, ty: Type, sc: Scatter, label: Option<&str>) -> bool {
        match self {
            Pred::Any => true,
            Pred::Types(m) => m & (1 << ty as u8) != 0,
            Pred::Scatters(m) => m & (1 << sc as u8) != 0,
            Pred::Label(l) => l.as_deref() == label,
            Pred::And(v) => v.iter().all(|p| p.matches(ty, sc, label)),
            Pred::Or(v) => v.iter().any(|p| p.matches(ty, sc, label)),
            Pred::Not(p) => !p.matches(ty, sc, label),
        }
    }
}

/// A parsed expression.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Node {
    /// Exactly one event satisfying the predicate.
    Event(Pred),
    Cat(Vec<Node>),
    Alt(Vec<Node>),
    /// `min` to `max` (unbounded if `None`) repetitions.
    Repeat(Box<Node>, u32, Option<u32>),
}

/// Number of event leaves once repeats are expanded (saturating).
fn size(node: &Node) -> usize {
    match node {
        Node::Event(_) => 1,
        Node::Cat(v) | Node::Alt(v) => v.iter().fold(0, |a, n| a.saturating_add(size(n))),
        Node::Repeat(n, min, max) => size(n).saturating_mul(max.unwrap_or(min + 1).max(1) as usize),
    }
}

/// Which meaning a letter gets: outside `<>`, or one of the three positions inside.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Slot {
    Bare,
    Type,
    Scatter,
    Label,
}

fn fail<T>(position: usize, message: impl Into<String>) -> Result<T, LpeError> {
    Err(LpeError::new(position, message))
}

/// The only element of `v`, or `many(v)`.
fn one_or<T>(mut v: Vec<T>, many: fn(Vec<T>) -> T) -> T {
    if v.len() == 1 {
        v.swap_remove(0)
    } else {
        many(v)
    }
}

fn and(preds: Vec<Pred>) -> Pred {
    let v: Vec<Pred> = preds.into_iter().filter(|p| *p != Pred::Any).collect();
    if v.is_empty() {
        Pred::Any
    } else {
        one_or(v, Pred::And)
    }
}

/// Gives letter `c` its meaning in `slot`; `at` is its position for errors.
fn resolve(c: char, slot: Slot, at: usize) -> Result<Pred, LpeError> {
    let ty = Type::from_letter(c);
    let sc = Scatter::from_letter(c);
    let known = ty.is_some() || sc.is_some();
    match (slot, ty, sc) {
        (Slot::Type | Slot::Bare, Some(t), _) => Ok(Pred::Types(1 << t as u8)),
        (Slot::Bare, _, Some(s)) if s != Scatter::None => Ok(Pred::Scatters(1 << s as u8)),
        (Slot::Scatter, _, Some(s)) => Ok(Pred::Scatters(1 << s as u8)),
        (Slot::Label, _, Some(Scatter::None)) => Ok(Pred::Label(None)),
        _ if !known => fail(at, format!("unknown event letter '{c}'")),
        (Slot::Bare, ..) => fail(at, "'x' (none) is only valid inside <...>"),
        (Slot::Type, ..) => fail(at, format!("'{c}' is not an event type (C R T L O B V)")),
        (Slot::Scatter, ..) => fail(at, format!("'{c}' is not a scattering (D G S x)")),
        (Slot::Label, ..) => fail(at, format!("'{c}' is not a label (write 'name', or x for none)")),
    }
}

struct Parser {
    s: Vec<char>,
    i: usize,
    depth: usize,
}

/// Parses one expression.
pub(crate) fn parse(text: &str) -> Result<Node, LpeError> {
    let mut p = Parser { s: text.chars().collect(), i: 0, depth: 0 };
    p.ws();
    if p.peek().is_none() {
        return fail(0, "empty expression");
    }
    let node = p.alt()?;
    match p.peek() {
        Some(c) => fail(p.i, format!("unmatched '{c}'")),
        None if size(&node) > MAX_SIZE => fail(0, "expression too long"),
        None => Ok(node),
    }
}

impl Parser {
    fn peek(&self) -> Option<char> {
        self.s.get(self.i).copied()
    }

    fn ws(&mut self) {
        while self.peek().is_some_and(char::is_whitespace) {
            self.i += 1;
        }
    }

    /// `cat ('|' cat)*`; stops before `)` or the end.
    fn alt(&mut self) -> Result<Node, LpeError> {
        let mut alts = Vec::new();
        let mut bar = None;
        loop {
            let items = self.cat()?;
            if items.is_empty() {
                return match bar {
                    Some(b) => fail(b, "nothing after '|'"),
                    None if self.peek() == Some('|') => fail(self.i, "nothing before '|'"),
                    None => fail(self.i, "expected an event"),
                };
            }
            alts.push(one_or(items, Node::Cat));
            if self.peek() != Some('|') {
                break;
            }
            bar = Some(self.i);
            self.i += 1;
        }
        Ok(one_or(alts, Node::Alt))
    }

    /// Postfix items up to `|`, `)` or the end.
    fn cat(&mut self) -> Result<Vec<Node>, LpeError> {
        let mut items = Vec::new();
        loop {
            self.ws();
            match self.peek() {
                None | Some('|' | ')') => return Ok(items),
                _ => items.push(self.postfix()?),
            }
        }
    }

    /// An atom with at most one repeat operator (as in OSL; `C**` is an error).
    fn postfix(&mut self) -> Result<Node, LpeError> {
        let node = self.primary()?;
        self.ws();
        let at = self.i;
        let (min, max) = match self.peek() {
            Some('*') => (0, None),
            Some('+') => (1, None),
            Some('?') => (0, Some(1)),
            Some('{') => self.range()?,
            _ => return Ok(node),
        };
        if self.i == at {
            self.i += 1;
        }
        let node = Node::Repeat(Box::new(node), min, max);
        if size(&node) > MAX_SIZE {
            return fail(at, "expression too large once repeats are expanded");
        }
        self.ws();
        match self.peek() {
            Some(c @ ('*' | '+' | '?' | '{')) => {
                fail(self.i, format!("'{c}' cannot follow another repeat; use parentheses"))
            }
            _ => Ok(node),
        }
    }

    /// `{n}`, `{n,}` or `{n,m}`.
    fn range(&mut self) -> Result<(u32, Option<u32>), LpeError> {
        let at = self.i;
        self.i += 1;
        let lo = self.number(at)?;
        let hi = if self.peek() == Some(',') {
            self.i += 1;
            self.number(at)?
        } else {
            lo
        };
        match (lo, self.peek()) {
            (Some(lo), Some('}')) => {
                self.i += 1;
                match hi {
                    Some(hi) if hi < lo => fail(at, format!("repeat range {{{lo},{hi}}} is backwards")),
                    _ => Ok((lo, hi)),
                }
            }
            _ => fail(at, "bad repeat range: expected {n}, {n,} or {n,m}"),
        }
    }

    fn number(&mut self, at: usize) -> Result<Option<u32>, LpeError> {
        self.ws();
        let start = self.i;
        let mut v: u32 = 0;
        while let Some(d) = self.peek().and_then(|c| c.to_digit(10)) {
            v = v.saturating_mul(10).saturating_add(d);
            self.i += 1;
        }
        self.ws();
        if v > MAX_COUNT {
            return fail(at, format!("repeat count above {MAX_COUNT}"));
        }
        Ok((self.i > start).then_some(v))
    }

    fn primary(&mut self) -> Result<Node, LpeError> {
        let at = self.i;
        let pred = match self.peek() {
            Some('(') => return self.group(),
            Some(c @ ('*' | '+' | '?' | '{')) => {
                return fail(at, format!("'{c}' has nothing before it to repeat"))
            }
            Some('\'') => Pred::Label(Some(self.label()?)),
            Some('<') => {
                let (p, has_label) = self.angle()?;
                self.shorthand(p, has_label)?
            }
            Some('[') => {
                let p = self.set(Slot::Bare)?;
                self.shorthand(p, false)?
            }
            _ => {
                let p = self.item(Slot::Bare)?;
                self.shorthand(p, false)?
            }
        };
        // An albedo event is matched only where the expression names it (`A`, `<A>`, `[AL]`):
        // `.`, negated sets and scattering letters leave it out.
        let pred = match pred.names(Type::Albedo) {
            true => pred,
            false => and(vec![pred, Pred::Not(Box::new(Pred::Types(1 << Type::Albedo as u8)))]),
        };
        Ok(Node::Event(pred))
    }

    fn group(&mut self) -> Result<Node, LpeError> {
        let open = self.i;
        if self.depth >= MAX_DEPTH {
            return fail(open, "parentheses nested too deeply");
        }
        self.i += 1;
        self.ws();
        if self.peek() == Some(')') {
            return fail(open, "empty group '()'");
        }
        self.depth += 1;
        let inner = self.alt()?;
        self.depth -= 1;
        if self.peek() != Some(')') {
            return fail(open, "unclosed '('");
        }
        self.i += 1;
        Ok(inner)
    }

    /// A letter, `.` or `'label'`, with its meaning in `slot`.
    fn item(&mut self, slot: Slot) -> Result<Pred, LpeError> {
        let at = self.i;
        let c = match self.peek() {
            Some('\'') if matches!(slot, Slot::Bare | Slot::Label) => {
                return Ok(Pred::Label(Some(self.label()?)))
            }
            Some('\'') => return fail(at, "a label cannot go in this position"),
            Some('.') => Ok('.'),
            Some(c) if c.is_alphabetic() => Ok(c),
            Some(c @ (')' | ']' | '>')) => fail(at, format!("unmatched '{c}'")),
            Some(c) => fail(at, format!("unexpected character '{c}'")),
            None => fail(at, "unexpected end of expression"),
        }?;
        self.i += 1;
        if c == '.' {
            return Ok(Pred::Any);
        }
        resolve(c, slot, at)
    }

    fn label(&mut self) -> Result<String, LpeError> {
        let open = self.i;
        self.i += 1;
        let start = self.i;
        while let Some(c) = self.peek() {
            self.i += 1;
            if c == '\'' {
                if self.i - 1 == start {
                    return fail(open, "empty label ''");
                }
                return Ok(self.s[start..self.i - 1].iter().collect());
            }
        }
        fail(open, "unterminated label (missing closing ')")
    }

    /// A `'label'` directly after an event restricts that event to the label.
    fn shorthand(&mut self, pred: Pred, has_label: bool) -> Result<Pred, LpeError> {
        if self.peek() != Some('\'') {
            return Ok(pred);
        }
        if has_label {
            return fail(self.i, "this event already has a label");
        }
        let label = self.label()?;
        if self.peek() == Some('\'') {
            return fail(self.i, "an event carries at most one label");
        }
        Ok(and(vec![pred, Pred::Label(Some(label))]))
    }

    /// `[..]` or `[^..]`, its items read in `slot`.
    fn set(&mut self, slot: Slot) -> Result<Pred, LpeError> {
        let open = self.i;
        self.i += 1;
        let negated = self.peek() == Some('^');
        if negated {
            self.i += 1;
        }
        let mut preds = Vec::new();
        loop {
            self.ws();
            match self.peek() {
                None => return fail(open, "unclosed '['"),
                Some(']') => break,
                Some(c) => {
                    let p = self.item(slot)?;
                    // Shorthand after a letter only: `['a''b']` is two labels.
                    let p = if slot == Slot::Bare && c != '\'' { self.shorthand(p, false)? } else { p };
                    preds.push(p);
                }
            }
        }
        self.i += 1;
        if preds.is_empty() {
            return fail(open, "empty set");
        }
        let p = one_or(preds, Pred::Or);
        Ok(if negated { Pred::Not(Box::new(p)) } else { p })
    }

    /// True if the next position (skipping `[`, `^`, spaces) starts with a label.
    fn label_ahead(&self) -> bool {
        let mut rest = self.s[self.i..].iter();
        rest.find(|c| !(matches!(c, '[' | '^') || c.is_whitespace())) == Some(&'\'')
    }

    /// `<type scattering label>`; returns the predicate and whether it names a label.
    fn angle(&mut self) -> Result<(Pred, bool), LpeError> {
        let open = self.i;
        self.i += 1;
        let mut slots = vec![Pred::Any, Pred::Any, Pred::Any];
        let mut pos = 0;
        loop {
            self.ws();
            let at = self.i;
            match self.peek() {
                None => return fail(open, "unclosed '<'"),
                Some('>') => break,
                Some('<') => return fail(at, "'<' cannot be nested"),
                Some(c @ ('*' | '+' | '?' | '{' | '(' | ')' | '|')) => {
                    return fail(at, format!("'{c}' is not allowed inside <...>"))
                }
                _ => {}
            }
            if pos < 2 && self.label_ahead() {
                pos = 2;
            }
            if pos > 2 {
                return fail(at, "an event carries at most one label");
            }
            let slot = [Slot::Type, Slot::Scatter, Slot::Label][pos];
            slots[pos] = if self.peek() == Some('[') { self.set(slot)? } else { self.item(slot)? };
            pos += 1;
        }
        self.i += 1;
        Ok((and(slots), pos > 2))
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{path, run};
    use super::super::Aovs;
    use super::*;

    /// Checks that `expr` matches each comma-separated path in `yes` and none in `no`
    /// (paths written as in [`path`]; scene labels a, b, key).
    fn t(expr: &str, yes: &str, no: &str) {
        let aovs =
            Aovs::compile(&[("t", expr)], &["a", "b", "key"]).unwrap_or_else(|e| panic!("{expr}: {}", e.1));
        for (paths, want) in [(yes, 1), (no, 0)] {
            for p in paths.split(',').filter(|p| !p.trim().is_empty()) {
                assert_eq!(run(&aovs, &path(p, aovs.labels())), want, "{expr:?} on {p:?}");
            }
        }
    }

    #[test]
    fn events() {
        t("CDL", "C RD L, C TD L", "C RG L, C RD, C RD L L");
        t("C<RD>L", "C RD L", "C TD L");
        t("C<R>L", "C RS L, C RD L", "C TS L");
        t("C<.G>L", "C TG L", "C TS L");
        t("C<[RT][^D]>L", "C TG L, C RS L", "C RD L");
        t("C<L x>", "C L, C L'a'", "C O");
        t("<C x x>", "C", "C'a'");
        t("C<L.'key'>", "C L'key'", "C L'a', C L, C O'key'");
        t("C<L'key'>", "C L'key'", "C L'a', C L"); // an early label skips to the label slot
        t("C<'key'>", "C RD'key', C O'key'", "C RD");
        t("C<L.x>", "C L", "C L'a'");
        t("C<L.[^'key']>", "C L'a', C L", "C L'key'");
        t("C<L.['a''b']>", "C L'b', C L'a'", "C L, C L'key'");
        t("C<>", "C RD'a', C B", "C");
        t("< C >", "C", "C L");
    }

    #[test]
    fn bare_letters_sets_labels() {
        t("C[GS]L", "C RG L, C TS L", "C RD L");
        t("C[^D]L", "C RG L, C B L", "C TD L");
        t("C[LO]", "C O, C L'a'", "C B");
        t("C[^LD]", "C B, C RG", "C L, C RD");
        t("C.'key'", "C L'key', C TS'key'", "C L");
        t("C 'key'", "C RD'key'", "C RD");
        t("C['a''b']", "C L'a', C RD'b'", "C L'key', C L");
        t("C[^'key']", "C L, C L'a'", "C L'key'");
        t("C[^'nope']", "C L'key'", ""); // labels the scene lacks never match
        t("C'nope'", "", "C L, C L'key'");
        t("CV", "C V, C VD", "C L");
        t("CB", "C B", "C L");
        t("CT", "C TS, C TD", "C RS");
    }

    #[test]
    fn shorthand_is_one_event() {
        t("C.*L'key'", "C RD L'key'", "C RD L'a', C RD L RD'key'");
        t("C<RD>'a'L", "C RD'a' L", "C RD L");
        t("CD'a'L", "C TD'a' L", "C TD L");
        t("C[LO]'key'", "C O'key'", "C O");
        t("C[L'key'O]", "C O, C L'key'", "C L");
        t("C 'a''b'", "C L'a' L'b'", "C L'a'"); // adjacent bare labels: two events
        t("CL 'key'", "C L L'key'", "C L'key'"); // with a space: two events
    }

    #[test]
    fn operators() {
        t("CD*L", "C L, C RD TD L", "C RG L");
        t("CD+L", "C RD L, C RD RD L", "C L");
        t("CD?L", "C L, C RD L", "C RD RD L");
        t("CD{2}L", "C RD RD L", "C RD L, C RD RD RD L");
        t("CD{ 1 , 2 }L", "C RD L, C RD RD L", "C L, C RD RD RD L");
        t("CD{2,}L", "C RD RD L, C RD RD RD RD L", "C RD L");
        t("CD{0}L", "C L", "C RD L");
        t("C(DG)*L", "C L, C RD RG RD RG L", "C RD L");
        t(".", "B, C", "C L");
        t(" C  D\tL ", "C RD L", "");
        t("C(D+)*L", "C L, C RD RD L", "C RG L");
        t("C(D*)+L", "C L, C RD RD L", "C RG L");
        assert_eq!(run(&Aovs::compile(&[("t", ".*")], &[]).unwrap(), &[]), 1);
    }

    #[test]
    fn alternation_binds_loosest() {
        // OSL's parser would read `CDL|CGL` as `C D (L|C) G L`.
        t("CDL|CGL", "C RD L, C RG L", "C RD RG L, C RD C RG L");
        t("C(D|G)L", "C RG L, C RD L", "C RS L");
        t("C(DL|GO)", "C RG O, C RD L", "C RD O");
        t("CL|CO|CB", "C B, C O, C L", "C RD L");
        t("(CL)|(CO)", "C O, C L", "C B");
    }

    #[test]
    fn garbage_never_panics() {
        let alphabet: Vec<char> = "CRTLOBVDGSxsQ.*+?|()[]<>^{},'0123 \u{fc}".chars().collect();
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = || {
            x = x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1);
            (x >> 33) as usize
        };
        for _ in 0..20_000 {
            let text: String = (0..next() % 14).map(|_| alphabet[next() % alphabet.len()]).collect();
            match parse(&text) {
                Ok(_) => assert!(Aovs::compile(&[("t", &text)], &["a"]).is_ok(), "{text:?}"),
                Err(e) => assert!(e.position <= text.chars().count(), "{text:?}: {e}"),
            }
        }
    }

    #[test]
    fn errors_name_their_position() {
        let cases: &[(&str, usize, &str)] = &[
            ("", 0, "empty expression"),
            ("   ", 0, "empty expression"),
            ("CRDQ", 3, "unknown event letter 'Q'"),
            ("C<RQ>", 3, "unknown event letter 'Q'"),
            ("C<DR>", 2, "'D' is not an event type"),
            ("C<RL>", 3, "'L' is not a scattering"),
            ("C<RDL>", 4, "'L' is not a label"),
            ("C<RD'a''b'>", 7, "at most one label"),
            ("C<R[D'a']>", 5, "a label cannot go in this position"),
            ("Cs", 1, "unknown event letter 's'"),
            ("Cx", 1, "only valid inside <...>"),
            ("C#", 1, "unexpected character '#'"),
            ("C(DL", 1, "unclosed '('"),
            ("C((D)L", 1, "unclosed '('"),
            ("CD)L", 2, "unmatched ')'"),
            ("C[DG", 1, "unclosed '['"),
            ("CD]", 2, "unmatched ']'"),
            ("C<RD", 1, "unclosed '<'"),
            ("CD>", 2, "unmatched '>'"),
            ("C<R<D>>", 3, "cannot be nested"),
            ("C<RD*>", 4, "not allowed inside <...>"),
            ("C()L", 1, "empty group"),
            ("C[]L", 1, "empty set"),
            ("C[^]L", 1, "empty set"),
            ("C<L.[^]>", 4, "empty set"),
            ("C'key", 1, "unterminated label"),
            ("C<L.'key>", 4, "unterminated label"),
            ("C''", 1, "empty label"),
            ("CL|", 2, "nothing after '|'"),
            ("|CL", 0, "nothing before '|'"),
            ("CL||CO", 2, "nothing after '|'"),
            ("C(|D)L", 2, "nothing before '|'"),
            ("C(D|)L", 3, "nothing after '|'"),
            ("*C", 0, "nothing before it to repeat"),
            ("C(*D)", 2, "nothing before it to repeat"),
            ("C|+D", 2, "nothing before it to repeat"),
            ("CD**L", 3, "cannot follow another repeat"),
            ("CD{2} ?L", 6, "cannot follow another repeat"),
            ("CD{}L", 2, "bad repeat range"),
            ("CD{,2}L", 2, "bad repeat range"),
            ("CD{2L", 2, "bad repeat range"),
            ("CD{3,2}L", 2, "backwards"),
            ("CD{65}L", 2, "above 64"),
            ("C(((D{60}){60}){60})", 15, "too large"),
            ("CL'a''b'", 5, "at most one label"),
            ("C<L'a'>'b'", 7, "already has a label"),
            ("C ü", 2, "unknown event letter 'ü'"),
        ];
        for &(expr, pos, msg) in cases {
            let e = parse(expr).map(|_| ()).expect_err(expr);
            assert_eq!(e.position, pos, "{expr:?}: {e}");
            assert!(e.message.contains(msg), "{expr:?}: {e}");
        }
        assert!(parse(&format!("C{}", "*".repeat(100_000))).is_err());
        assert!(parse(&"C".repeat(20_000)).is_err() && parse(&"C".repeat(9_000)).is_ok());
        assert!(
            parse(&"(".repeat(100)).is_err()
                && parse(&format!("{}C{}", "(".repeat(60), ")".repeat(60))).is_ok()
        );
        assert_eq!(parse("CRDQ").unwrap_err().to_string(), "column 4: unknown event letter 'Q'");
        assert!(parse("RL").is_ok() && parse("L").is_ok(), "need not start with C");
    }
}
