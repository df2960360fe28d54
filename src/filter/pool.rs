//! The filter's working planes, kept between calls. A 256x256 `--denoise` works in about 16 MB of
//! planes; freshly allocated, every 4 KB page of them is a page fault when first written and
//! an unmapping when freed, which took about a third of a warm call (docs/RESULTS.md, the
//! denoising section). A plane taken here reuses one that an earlier call, or an earlier step
//! of this one, gave back; planes are given back when dropped, as long as the pool holds at
//! most [`KEEP_BYTES`], so a process that filtered a 4K image does not keep its gigabytes.
//! Planes too large to keep (from [`MAPPED_MIN`]: a 4K image's) are mapped in transparent huge
//! pages instead, one fault for 2 MB rather than for 4 KB: at 4K the kernel's page faults and
//! zeroing took three quarters of a call (docs/RESULTS.md).

use std::ops::{Deref, DerefMut};
use std::sync::Mutex;

/// The most the pool keeps between uses: a 512x512 `--denoise`'s planes, about 80 MB.
pub const KEEP_BYTES: usize = 96 << 20;

/// Planes given back and not yet taken again, and the bytes they hold.
static POOL: Mutex<(Vec<Vec<f32>>, usize)> = Mutex::new((Vec::new(), 0));

fn lock() -> std::sync::MutexGuard<'static, (Vec<Vec<f32>>, usize)> {
    // A poisoned lock only means another thread panicked while holding it; the planes in it
    // are whole either way.
    POOL.lock().unwrap_or_else(|e| e.into_inner())
}

/// A plane of `f32` taken from the pool (or allocated when none there is large enough), set to
/// zero, and given back to the pool when dropped.
pub struct Plane(Store);

enum Store {
    Heap(Vec<f32>),
    /// A plane larger than the pool keeps, in huge pages where the system gives them.
    Mapped(crate::accel::bvh::pages::Pages<f32>),
}

/// Planes of at least this many bytes are never kept, and get huge pages.
const MAPPED_MIN: usize = 32 << 20;

impl Plane {
    /// `n` zeros (the pool's tests; the filter writes its planes whole).
    #[cfg(test)]
    pub fn zeroed(n: usize) -> Plane {
        Plane::of(n, true)
    }

    /// `n` floats of unspecified values (a plane given back keeps its old ones): for a plane
    /// its caller writes whole before reading, without a pass that zeroes it first (at 256x256
    /// `--denoise` zeroed about 12 MB a call that it then wrote over).
    pub fn overwritten(n: usize) -> Plane {
        Plane::of(n, false)
    }

    fn of(n: usize, zeroed: bool) -> Plane {
        if n * size_of::<f32>() >= MAPPED_MIN {
            return Plane(Store::Mapped(crate::accel::bvh::pages::Pages::zeroed(n)));
        }
        match take(n) {
            Some(mut v) => {
                // Zeroed: every value written again; else only those past the old length.
                v.truncate(if zeroed { 0 } else { n });
                v.resize(n, 0.0);
                Plane(Store::Heap(v))
            }
            // New memory from the system is zero already: its pages are touched (and faulted
            // in) only by whichever threads write them first, not all here, by this one.
            None => Plane(Store::Heap(vec![0.0; n])),
        }
    }
}

/// The smallest pooled vector that holds `n` floats without growing (its contents
/// unspecified).
fn take(n: usize) -> Option<Vec<f32>> {
    let mut pool = lock();
    let (planes, bytes) = &mut *pool;
    let best = planes.iter().enumerate().filter(|(_, v)| v.capacity() >= n).min_by_key(|(_, v)| v.capacity());
    let v = planes.swap_remove(best?.0);
    *bytes -= v.capacity() * size_of::<f32>();
    Some(v)
}

impl Drop for Plane {
    fn drop(&mut self) {
        let Store::Heap(v) = &mut self.0 else { return };
        let v = std::mem::take(v);
        let size = v.capacity() * size_of::<f32>();
        if size == 0 {
            return;
        }
        let mut pool = lock();
        let (planes, bytes) = &mut *pool;
        if *bytes + size <= KEEP_BYTES {
            *bytes += size;
            planes.push(v);
        }
    }
}

impl Deref for Plane {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        match &self.0 {
            Store::Heap(v) => v,
            Store::Mapped(p) => p,
        }
    }
}

impl DerefMut for Plane {
    fn deref_mut(&mut self) -> &mut [f32] {
        match &mut self.0 {
            Store::Heap(v) => v,
            Store::Mapped(p) => p,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_plane_is_zeros_of_its_length_whatever_was_given_back() {
        // A plane written and given back, then planes of other lengths taken: each is all zeros.
        let mut p: Plane = Plane::zeroed(1000);
        p.iter_mut().enumerate().for_each(|(i, v)| *v = i as f32 + 1.0);
        drop(p);
        for n in [10, 1000, 999, 4000] {
            let p: Plane = Plane::zeroed(n);
            assert_eq!(p.len(), n);
            assert!(p.iter().all(|&v| v == 0.0), "a plane of {n} is not all zeros");
        }
    }

    #[test]
    fn a_plane_to_overwrite_has_its_length_whatever_was_given_back() {
        for n in [1000, 10, 999, 4000, 0] {
            let mut p = Plane::overwritten(n);
            assert_eq!(p.len(), n);
            p.iter_mut().for_each(|v| *v = 7.0);
        }
    }

    #[test]
    fn a_plane_too_large_to_keep_is_zeros_and_holds_its_values() {
        let n = MAPPED_MIN / size_of::<f32>() + 5;
        let mut p = Plane::zeroed(n);
        assert_eq!(p.len(), n);
        assert!(p.iter().all(|&v| v == 0.0));
        p.iter_mut().enumerate().for_each(|(i, v)| *v = i as f32);
        assert!(p.iter().enumerate().all(|(i, &v)| v == i as f32));
    }

    #[test]
    fn the_pool_keeps_no_more_than_its_limit() {
        // Planes larger than the limit together: dropping them all leaves at most the limit.
        let n = MAPPED_MIN / size_of::<f32>() - 1;
        let count = KEEP_BYTES / MAPPED_MIN + 2;
        let planes: Vec<Plane> = (0..count).map(|_| Plane::zeroed(n)).collect();
        drop(planes);
        // (Other tests take and give back planes meanwhile; the limit holds at every moment.)
        let bytes = lock().1;
        assert!(bytes <= KEEP_BYTES, "the pool holds {bytes} bytes, above {KEEP_BYTES}");
    }
}
