//! Memory for the wide tree's nodes and leaves: a fixed-length array that, from a few
//! megabytes on, is mapped on its own and advised for transparent huge pages (Linux
//! `madvise(MADV_HUGEPAGE)`, through `memmap2`).
//!
//! Rays in random order touch the whole tree, tens of megabytes at a million triangles. In 4 KiB
//! pages that is far more pages than the TLB holds, so most node and leaf reads also walk the
//! page table; in 2 MiB pages the whole tree takes a few dozen TLB entries. Embree maps its BVH
//! the same way (its memory shows as `AnonHugePages` in `/proc/self/smaps_rollup`). Where the
//! OS gives no mapping or no huge pages, the array is ordinary memory: only speed differs.

use std::ops::{Deref, DerefMut};

use bytemuck::Pod;

/// Arrays of at least this many bytes get a mapping of their own (smaller ones sit in a few
/// pages anyway).
const MAPPED_MIN: usize = 2 << 20;
/// A transparent huge page on x86-64 and most ARM systems: mappings are sized in these, so that
/// the kernel can back all of one with them.
const HUGE_PAGE: usize = 2 << 20;

/// A fixed-length array of `T`, in its own huge-page mapping when it is large.
pub struct Pages<T: Pod> {
    store: Store<T>,
    len: usize,
}

enum Store<T> {
    Heap(Vec<T>),
    Mapped(memmap2::MmapMut),
}

impl<T: Pod> Pages<T> {
    /// `len` all-zero values (a mapping starts zeroed, so nothing is written).
    pub fn zeroed(len: usize) -> Pages<T> {
        let bytes = len * std::mem::size_of::<T>();
        // A mapping is page aligned, which every `T` here (64 bytes at most) is content with.
        if bytes >= MAPPED_MIN && std::mem::align_of::<T>() <= 4096 {
            if let Ok(map) = memmap2::MmapMut::map_anon(bytes.next_multiple_of(HUGE_PAGE)) {
                // Advice only: where the kernel declines, the mapping is ordinary memory.
                let _ = map.advise(advice());
                return Pages { store: Store::Mapped(map), len };
            }
        }
        Pages { store: Store::Heap(vec![T::zeroed(); len]), len }
    }

    /// Whether the array has a mapping of its own.
    #[cfg(test)]
    pub fn is_mapped(&self) -> bool {
        matches!(self.store, Store::Mapped(_))
    }
}

#[cfg(target_os = "linux")]
fn advice() -> memmap2::Advice {
    memmap2::Advice::HugePage
}

#[cfg(not(target_os = "linux"))]
fn advice() -> memmap2::Advice {
    memmap2::Advice::Normal
}

impl<T: Pod> Deref for Pages<T> {
    type Target = [T];

    fn deref(&self) -> &[T] {
        match &self.store {
            Store::Heap(v) => v,
            Store::Mapped(map) => bytemuck::cast_slice(&map[..self.len * std::mem::size_of::<T>()]),
        }
    }
}

impl<T: Pod> DerefMut for Pages<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        match &mut self.store {
            Store::Heap(v) => v,
            Store::Mapped(map) => bytemuck::cast_slice_mut(&mut map[..self.len * std::mem::size_of::<T>()]),
        }
    }
}

impl<T: Pod> Default for Pages<T> {
    fn default() -> Self {
        Pages { store: Store::Heap(Vec::new()), len: 0 }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Small arrays stay on the heap, large ones are mapped; both hold what was written, and
    /// a mapped array's elements are where a slice of them says.
    #[test]
    fn small_on_the_heap_large_mapped_both_hold_their_values() {
        let mut small = Pages::zeroed(1000);
        assert!(!small.is_mapped());
        assert!(small.iter().all(|x| *x == [0u32; 16]));
        small.fill([7u32; 16]);
        assert!(small.iter().all(|x| *x == [7; 16]));
        let items: Vec<[u32; 16]> = (0..100_000u32).map(|i| [i; 16]).collect();
        let mut large = Pages::zeroed(items.len());
        assert!(large.iter().all(|x| *x == [0u32; 16]));
        large.copy_from_slice(&items);
        assert!(large.is_mapped(), "{} bytes", large.len() * 64);
        assert_eq!(large.len(), items.len());
        assert!(large.iter().zip(&items).all(|(a, b)| a == b));
        large[99_999][3] = 5;
        assert_eq!(large[99_999], {
            let mut x = [99_999; 16];
            x[3] = 5;
            x
        });
        assert_eq!((large.as_ptr() as usize) % 64, 0);
    }
}
