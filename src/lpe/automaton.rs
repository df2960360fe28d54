//! Parsed expressions -> one union NFA (Thompson) -> subset construction -> Moore
//! minimisation -> flat transition table. Everything is ordered (BTreeMap, vectors),
//! so the same expressions always give the same numbering.

use super::parse::{Node, Pred};
use super::{Labels, LpeError, Scatter, Type};
use std::collections::BTreeMap;

/// Number of `(type, scattering)` pairs.
const PAIRS: usize = Type::ALL.len() * Scatter::ALL.len();

/// Whether the renderer produces `(ty, sc)`: `C L O B` have no scattering, `R T` always
/// have one, `V` may have either.
pub(crate) fn valid(ty: Type, sc: Scatter) -> bool {
    match ty {
        Type::Camera | Type::Light | Type::Object | Type::Background | Type::Albedo => sc == Scatter::None,
        Type::Reflection | Type::Transmission => sc != Scatter::None,
        Type::Volume => true,
    }
}

/// The compiled automaton. State 0 is the absorbing dead state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Dfa {
    /// Symbol class of event `(type * 4 + scatter) * (labels + 1) + label`.
    pub(crate) classes: Vec<u32>,
    pub(crate) nclasses: usize,
    /// `table[state * nclasses + class]` = next state.
    pub(crate) table: Vec<u16>,
    pub(crate) accept: Vec<u64>,
    pub(crate) start: u16,
}

/// Thompson NFA; `tag[s]` has bit i if s is expression i's accepting state.
#[derive(Default)]
struct Nfa {
    eps: Vec<Vec<usize>>,
    edges: Vec<Vec<(usize, usize)>>,
    tag: Vec<u64>,
    atoms: BTreeMap<Pred, usize>,
}

impl Nfa {
    fn state(&mut self) -> usize {
        self.eps.push(Vec::new());
        self.edges.push(Vec::new());
        self.tag.push(0);
        self.eps.len() - 1
    }

    /// Adds a fragment for `node`; returns its entry and exit states.
    fn build(&mut self, node: &Node) -> (usize, usize) {
        let (s, e) = (self.state(), self.state());
        let mut cur = s;
        match node {
            Node::Event(p) => {
                let next = self.atoms.len();
                let atom = *self.atoms.entry(p.clone()).or_insert(next);
                self.edges[s].push((atom, e));
                return (s, e);
            }
            Node::Alt(v) => {
                for n in v {
                    let (a, b) = self.build(n);
                    self.eps[s].push(a);
                    self.eps[b].push(e);
                }
                return (s, e);
            }
            Node::Cat(v) => {
                for n in v {
                    let (a, b) = self.build(n);
                    self.eps[cur].push(a);
                    cur = b;
                }
            }
            Node::Repeat(n, min, max) => {
                for _ in 0..*min {
                    let (a, b) = self.build(n);
                    self.eps[cur].push(a);
                    cur = b;
                }
                match max {
                    None => {
                        let (a, b) = self.build(n);
                        self.eps[cur].push(a);
                        self.eps[b].push(cur);
                    }
                    Some(max) => {
                        for _ in *min..*max {
                            let (a, b) = self.build(n);
                            self.eps[cur].extend([a, e]);
                            cur = b;
                        }
                    }
                }
            }
        }
        self.eps[cur].push(e);
        (s, e)
    }

    /// Epsilon closure of `stack`, keeping only the states that matter to a DFA state
    /// (those with event edges or an accept tag), sorted.
    fn closure(&self, mut stack: Vec<usize>, seen: &mut [bool]) -> Vec<usize> {
        let mut out = Vec::new();
        while let Some(s) = stack.pop() {
            if !std::mem::replace(&mut seen[s], true) {
                out.push(s);
                stack.extend(&self.eps[s]);
            }
        }
        for &s in &out {
            seen[s] = false;
        }
        out.retain(|&s| !self.edges[s].is_empty() || self.tag[s] != 0);
        out.sort_unstable();
        out
    }
}

/// Builds the minimal DFA over the union of `exprs` (at most 64).
pub(crate) fn build(exprs: &[Node], labels: &Labels) -> Result<Dfa, LpeError> {
    let mut nfa = Nfa::default();
    let root = nfa.state();
    for (i, e) in exprs.iter().enumerate() {
        let (a, b) = nfa.build(e);
        nfa.eps[root].push(a);
        nfa.tag[b] |= 1 << i;
    }
    let mut atoms = vec![Pred::Any; nfa.atoms.len()];
    for (p, &i) in &nfa.atoms {
        atoms[i] = p.clone();
    }

    // Symbol classes: events that satisfy exactly the same atoms are interchangeable.
    let nl1 = labels.len() + 1;
    let mut ids: BTreeMap<Vec<bool>, u32> = BTreeMap::new();
    let mut class_atoms: Vec<Vec<bool>> = Vec::new();
    let mut classes = Vec::with_capacity(PAIRS * nl1);
    for sym in 0..PAIRS * nl1 {
        let (pair, label) = (sym / nl1, sym % nl1);
        let (ty, sc) = (Type::ALL[pair / 4], Scatter::ALL[pair % 4]);
        let name = u16::try_from(label).ok().and_then(|l| labels.name(l));
        // Pairs the renderer never produces match nothing, so they cannot split states.
        let sig: Vec<bool> = atoms.iter().map(|p| valid(ty, sc) && p.matches(ty, sc, name)).collect();
        let next = class_atoms.len() as u32;
        let id = *ids.entry(sig.clone()).or_insert_with(|| {
            class_atoms.push(sig);
            next
        });
        classes.push(id);
    }
    let k = class_atoms.len();

    // Subset construction; DFA state 0 is the empty set (dead).
    let mut seen = vec![false; nfa.eps.len()];
    let mut sets: Vec<Vec<usize>> = vec![Vec::new()];
    let mut index: BTreeMap<Vec<usize>, usize> = BTreeMap::from([(Vec::new(), 0)]);
    let start_set = nfa.closure(vec![root], &mut seen);
    let mut intern = |set: Vec<usize>, sets: &mut Vec<Vec<usize>>| -> Result<usize, LpeError> {
        if let Some(&id) = index.get(&set) {
            return Ok(id);
        }
        if sets.len() >= usize::from(u16::MAX) {
            return Err(LpeError::new(0, "the automaton would exceed 65535 states"));
        }
        index.insert(set.clone(), sets.len());
        sets.push(set);
        Ok(sets.len() - 1)
    };
    let start = intern(start_set, &mut sets)?;
    let atom_classes: Vec<Vec<usize>> =
        (0..atoms.len()).map(|a| (0..k).filter(|&c| class_atoms[c][a]).collect()).collect();
    let mut targets: Vec<Vec<usize>> = vec![Vec::new(); k];
    let mut trans: Vec<usize> = Vec::new();
    let mut i = 0;
    while i < sets.len() {
        for &(atom, t) in sets[i].iter().flat_map(|&s| &nfa.edges[s]) {
            atom_classes[atom].iter().for_each(|&c| targets[c].push(t));
        }
        for class_targets in &mut targets {
            let t = nfa.closure(std::mem::take(class_targets), &mut seen);
            trans.push(intern(t, &mut sets)?);
        }
        i += 1;
    }
    let masks: Vec<u64> = sets.iter().map(|s| s.iter().fold(0, |m, &n| m | nfa.tag[n])).collect();
    Ok(minimise(&trans, &masks, k, start, classes))
}

/// Moore partition refinement, then renumbering in breadth-first order from the start
/// (dead block = 0). States that can never accept all fall into the dead block.
fn minimise(trans: &[usize], masks: &[u64], k: usize, start: usize, classes: Vec<u32>) -> Dfa {
    let n = masks.len();
    let mut block: Vec<usize> = {
        let mut ids = BTreeMap::new();
        masks
            .iter()
            .map(|m| {
                let next = ids.len();
                *ids.entry(*m).or_insert(next)
            })
            .collect()
    };
    let mut count = 0;
    loop {
        let mut ids: BTreeMap<Vec<usize>, usize> = BTreeMap::new();
        let refined: Vec<usize> = (0..n)
            .map(|s| {
                let mut key = vec![block[s]];
                key.extend(trans[s * k..(s + 1) * k].iter().map(|&t| block[t]));
                let next = ids.len();
                *ids.entry(key).or_insert(next)
            })
            .collect();
        block = refined;
        if ids.len() == count {
            break;
        }
        count = ids.len();
    }
    let mut rep = vec![usize::MAX; count];
    for s in (0..n).rev() {
        rep[block[s]] = s;
    }
    let mut new_id = vec![u16::MAX; count];
    let mut order = vec![block[0]];
    new_id[block[0]] = 0;
    let mut j = 0;
    let mut visit = |b: usize, order: &mut Vec<usize>| {
        if new_id[b] == u16::MAX {
            new_id[b] = order.len() as u16;
            order.push(b);
        }
        new_id[b]
    };
    let start = visit(block[start], &mut order);
    let mut table = Vec::new();
    while j < order.len() {
        let r = rep[order[j]];
        for c in 0..k {
            let t = visit(block[trans[r * k + c]], &mut order);
            table.push(t);
        }
        j += 1;
    }
    let accept = order.iter().map(|&b| masks[rep[b]]).collect();
    Dfa { classes, nclasses: k, table, accept, start }
}

#[cfg(test)]
mod tests {
    use super::super::testing::run;
    use super::super::{parse::parse, Aovs, State, BUILTINS};
    use super::*;

    /// Fixed-seed xorshift64.
    struct Rng(u64);
    impl Rng {
        fn below(&mut self, n: usize) -> usize {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 % n as u64) as usize
        }
        fn pick<'a>(&mut self, xs: &[&'a str]) -> &'a str {
            xs[self.below(xs.len())]
        }
    }

    const SCENE: [&str; 3] = ["a", "b", "c"];
    type Ev = (Type, Scatter, u16);

    fn name(l: u16) -> Option<&'static str> {
        l.checked_sub(1).map(|i| SCENE[usize::from(i)])
    }

    /// Backtracking matcher straight on the tree: can `node` match `path[i..j]` for a
    /// `j` that `k` accepts?
    fn bt(node: &Node, path: &[Ev], i: usize, k: &mut dyn FnMut(usize) -> bool) -> bool {
        match node {
            Node::Event(p) => i < path.len() && p.matches(path[i].0, path[i].1, name(path[i].2)) && k(i + 1),
            Node::Alt(v) => v.iter().any(|n| bt(n, path, i, k)),
            Node::Cat(v) => cat(v, path, i, k),
            // One more round, then the rest; past the minimum a round must consume
            // something, or `(D*)*` would never end.
            Node::Repeat(n, min, max) => {
                let rest = Node::Repeat(n.clone(), min.saturating_sub(1), max.map(|m| m.saturating_sub(1)));
                (*min == 0 && k(i))
                    || (*max != Some(0)
                        && bt(n, path, i, &mut |j| (j > i || *min > 0) && bt(&rest, path, j, k)))
            }
        }
    }
    fn cat(v: &[Node], path: &[Ev], i: usize, k: &mut dyn FnMut(usize) -> bool) -> bool {
        match v.split_first() {
            None => k(i),
            Some((h, t)) => bt(h, path, i, &mut |j| cat(t, path, j, k)),
        }
    }
    fn brute(node: &Node, path: &[Ev]) -> bool {
        bt(node, path, 0, &mut |j| j == path.len())
    }

    fn random_event(r: &mut Rng) -> Ev {
        loop {
            let (ty, sc) = (Type::ALL[r.below(Type::ALL.len())], Scatter::ALL[r.below(4)]);
            if valid(ty, sc) {
                return (ty, sc, r.below(4) as u16);
            }
        }
    }

    /// A random path that `node` tends to match (then the caller may mutate it).
    fn sample(node: &Node, r: &mut Rng, out: &mut Vec<Ev>) {
        match node {
            Node::Event(p) => {
                let mut e = random_event(r);
                for _ in 0..64 {
                    if p.matches(e.0, e.1, name(e.2)) {
                        break;
                    }
                    e = random_event(r);
                }
                out.push(e);
            }
            Node::Cat(v) => v.iter().for_each(|n| sample(n, r, out)),
            Node::Alt(v) => sample(&v[r.below(v.len())], r, out),
            Node::Repeat(n, min, max) => {
                let extra = max.map_or(2, |m| (m - min).min(2)) as usize;
                for _ in 0..*min as usize + r.below(extra + 1) {
                    sample(n, r, out);
                }
            }
        }
    }

    /// One random event: bare letter, `.`, label, set, `<...>` or shorthand.
    fn gen_event(r: &mut Rng) -> String {
        const BARE: &[&str] = &["C", "R", "T", "L", "O", "B", "V", "D", "G", "S", ".", "'a'", "'zz'"];
        const TYPE: &[&str] = &["C", "R", "T", "L", "O", "V", ".", "[RT]", "[^LO]", "[CL]"];
        const SCAT: &[&str] = &["D", "G", "S", "x", ".", "[GS]", "[^D]", "[xD]"];
        const LABEL: &[&str] = &["'a'", "'b'", "x", ".", "[^'a']", "['a''zz']", "[^x]"];
        let pos = r.below(4);
        match r.below(6) {
            0 => {
                let mut body = String::from(if r.below(3) == 0 { "[^" } else { "[" });
                for _ in 0..1 + r.below(3) {
                    let item = r.pick(BARE);
                    // `R'a''b'` (two labels on one event) is an error: keep it out.
                    if body.ends_with('\'') && item.starts_with('\'') {
                        body.push(' ');
                    }
                    body += item;
                }
                body + "]"
            }
            1 | 2 => {
                let parts = [r.pick(TYPE), r.pick(SCAT), r.pick(LABEL)];
                format!("<{}>", parts[..pos.min(3)].concat())
            }
            3 => [r.pick(&["L", "O", "D", ".", "<RD>", "[LO]"]), r.pick(&["'a'", "'zz'"])].concat(),
            _ => r.pick(BARE).into(),
        }
    }

    fn gen(r: &mut Rng, depth: u32) -> String {
        if depth == 0 || r.below(4) == 0 {
            return gen_event(r);
        }
        let post = ["*", "+", "?", "{2}", "{0,2}", "{1,}", "{1,3}"][r.below(7)];
        let (a, b) = (gen(r, depth - 1), gen(r, depth - 1));
        match r.below(6) {
            // `L'a'` then `'b'` written together would be one event with two labels.
            0 | 1 if b.starts_with('\'') => format!("{a} {b}"),
            0 | 1 => format!("{a}{b}"),
            2 => format!("({a}|{b})"),
            3 => format!("{a} {b}|{}", gen(r, depth - 1)),
            4 => format!("({a}){post}"),
            _ => format!("{}{post}", gen_event(r)),
        }
    }

    #[test]
    fn automaton_agrees_with_backtracking() {
        let mut r = Rng(0x2545_F491_4F6C_DD1D);
        let (mut total, mut positive, mut max_states) = (0, 0, 0);
        for _ in 0..2000 {
            let n = 1 + r.below(4);
            let texts: Vec<String> = (0..n).map(|_| format!("C{}", gen(&mut r, 4))).collect();
            let trees: Vec<Node> =
                texts.iter().map(|t| parse(t).unwrap_or_else(|e| panic!("{t}: {e}"))).collect();
            let exprs: Vec<(&str, &str)> = texts.iter().map(|t| ("t", t.as_str())).collect();
            let aovs = Aovs::compile(&exprs, &SCENE).unwrap();
            max_states = max_states.max(aovs.states());
            for _ in 0..30 {
                let mut path = Vec::new();
                if r.below(3) == 0 {
                    (0..r.below(7)).for_each(|_| path.push(random_event(&mut r)));
                } else {
                    sample(&trees[r.below(n)], &mut r, &mut path);
                    path.truncate(12);
                    if r.below(4) == 0 && !path.is_empty() {
                        let at = r.below(path.len());
                        path[at] = random_event(&mut r);
                    }
                }
                let want =
                    trees.iter().enumerate().fold(0, |m, (i, t)| m | (u64::from(brute(t, &path)) << i));
                assert_eq!(run(&aovs, &path), want, "{texts:?} on {path:?}");
                total += 1;
                positive += usize::from(want != 0);
            }
        }
        println!(
            "brute force: {total} paths, {positive} matched something, largest automaton {max_states} states"
        );
        assert!(positive * 4 > total, "too few matching paths to mean anything");
    }

    #[test]
    fn deterministic() {
        let a = Aovs::compile(BUILTINS, &SCENE).unwrap();
        let b = Aovs::compile(BUILTINS, &SCENE).unwrap();
        assert_eq!(a, b);
        let mut r = Rng(7);
        for _ in 0..50 {
            let texts: Vec<String> = (0..3).map(|_| gen(&mut r, 4)).collect();
            let exprs: Vec<(&str, &str)> = texts.iter().map(|t| ("t", t.as_str())).collect();
            assert_eq!(Aovs::compile(&exprs, &SCENE).unwrap(), Aovs::compile(&exprs, &SCENE).unwrap());
        }
    }

    #[test]
    fn minimal_and_dead() {
        // `C(D|D)L` and `CDL` are the same language: same automaton.
        let a = Aovs::compile(&[("x", "C(D|D)L")], &[]).unwrap();
        let b = Aovs::compile(&[("x", "CDL")], &[]).unwrap();
        assert_eq!(a.dfa, b.dfa);
        assert_eq!(a.states(), 5, "dead, start, C, CD, CDL");
        // A language that can never match has only the dead state.
        let never = Aovs::compile(&[("x", "C'zz'")], &SCENE).unwrap();
        assert_eq!((never.states(), never.start()), (1, State::DEAD));
        // Events the renderer never produces (a diffuse light, a reflection without
        // scattering) kill the path even under `.*`.
        let all = Aovs::compile(&[("x", ".*")], &SCENE).unwrap();
        let step = |t, sc| all.next(all.start(), all.symbol(t, sc, 2));
        assert_eq!(all.states(), 2);
        assert_ne!(step(Type::Volume, Scatter::Diffuse), State::DEAD);
        assert_eq!(step(Type::Light, Scatter::Diffuse), State::DEAD);
        assert_eq!(step(Type::Reflection, Scatter::None), State::DEAD);
    }
}
