//! The paper's light-path components (section 2) as one type: every place that splits, stores,
//! names, filters or writes radiance by light path goes through [`Component`] and [`Split`], so
//! no component is ever addressed by a bare index. Imports nothing.

use std::ops::{Index, IndexMut};

/// A light-path component, in Heckbert's notation read from the eye (E eye, S a specular-like
/// bounce, D a diffuse-like one, L a light), with `x` the first D vertex.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Component {
    /// L_e: E S* L, no D vertex at all.
    Emitted,
    /// L_r,d,l: E S* D L.
    Direct,
    /// L_r,d,s: E S* D S+ L.
    Caustic,
    /// L_r,d,d: some D vertex after `x` (or a diffuse source's light at `x`): what the paper
    /// filters.
    Indirect,
}

impl Component {
    /// Every component, in layer order.
    pub const ALL: [Component; 4] =
        [Component::Emitted, Component::Direct, Component::Caustic, Component::Indirect];

    /// The layer name (`emitted`, `direct`, `caustic`, `indirect`).
    pub const fn name(self) -> &'static str {
        match self {
            Component::Emitted => "emitted",
            Component::Direct => "direct",
            Component::Caustic => "caustic",
            Component::Indirect => "indirect",
        }
    }

    /// The component with this layer name.
    pub fn from_name(name: &str) -> Option<Component> {
        Component::ALL.into_iter().find(|c| c.name() == name)
    }

    /// Its position in [`Component::ALL`] (and in a [`Split`]).
    pub const fn index(self) -> usize {
        self as usize
    }
}

/// One value per component, indexed by [`Component`]: a sample's radiance split by light path,
/// or a film's four component layers.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Split<T>([T; 4]);

impl<T> Split<T> {
    /// The split whose value for `c` is `f(c)`.
    pub fn from_fn(mut f: impl FnMut(Component) -> T) -> Self {
        Split(Component::ALL.map(&mut f))
    }

    /// The values in [`Component::ALL`] order.
    pub fn iter(&self) -> std::slice::Iter<'_, T> {
        self.0.iter()
    }

    /// The values in [`Component::ALL`] order, mutably.
    pub fn iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
        self.0.iter_mut()
    }

    /// Each component with its value.
    pub fn named(&self) -> impl Iterator<Item = (Component, &T)> {
        Component::ALL.into_iter().zip(&self.0)
    }

    /// Each component with its value, mutably.
    pub fn named_mut(&mut self) -> impl Iterator<Item = (Component, &mut T)> {
        Component::ALL.into_iter().zip(&mut self.0)
    }

    /// The split of `f` applied to each value.
    pub fn map<U>(self, f: impl FnMut(T) -> U) -> Split<U> {
        Split(self.0.map(f))
    }
}

impl<T> Index<Component> for Split<T> {
    type Output = T;
    fn index(&self, c: Component) -> &T {
        &self.0[c.index()]
    }
}

impl<T> IndexMut<Component> for Split<T> {
    fn index_mut(&mut self, c: Component) -> &mut T {
        &mut self.0[c.index()]
    }
}

impl<'a, T> IntoIterator for &'a Split<T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<'a, T> IntoIterator for &'a mut Split<T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.iter_mut()
    }
}

impl<T> IntoIterator for Split<T> {
    type Item = T;
    type IntoIter = std::array::IntoIter<T, 4>;
    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_indices_round_trip() {
        for (i, c) in Component::ALL.into_iter().enumerate() {
            assert_eq!(c.index(), i);
            assert_eq!(Component::from_name(c.name()), Some(c));
        }
        assert_eq!(Component::from_name("beauty"), None);
        let s = Split::from_fn(|c| c.name().len());
        assert_eq!(s[Component::Caustic], "caustic".len());
        assert_eq!(s.named().map(|(c, _)| c).collect::<Vec<_>>(), Component::ALL);
    }
}
