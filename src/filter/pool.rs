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

use glam::Vec3;
use rayon::prelude::*;

use crate::film::Image;

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

/// Planes of at least this many bytes are never kept, and get huge pages (but [`Pixels`]).
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

    /// [`Plane::overwritten`], in ordinary memory whatever its size: a plane too large to
    /// keep is a fresh allocation, never a mapping of its own.
    fn heap(n: usize) -> Plane {
        Plane::of_in(n, false, false)
    }

    fn of(n: usize, zeroed: bool) -> Plane {
        Plane::of_in(n, zeroed, true)
    }

    /// `n` floats, zeroed or not; from [`MAPPED_MIN`] never kept, and `mapped` in huge pages.
    fn of_in(n: usize, zeroed: bool, mapped: bool) -> Plane {
        if n * size_of::<f32>() >= MAPPED_MIN {
            return Plane(match mapped {
                true => Store::Mapped(crate::accel::bvh::pages::Pages::zeroed(n)),
                false => Store::Heap(vec![0.0; n]),
            });
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
        // Too large to keep (an image of [`Pixels`] that size is on the heap, not mapped).
        if size == 0 || size >= MAPPED_MIN {
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

/// An image's pixels in a [`Plane`] (three floats a pixel): the images a filter call makes
/// between its steps (the halves, the filtered layers), reused between calls like its planes
/// and written without being zeroed first. Never in huge pages: the thirteen 100 MB images of a
/// 4K `--denoise` mapped so took the call 1.04x to 1.1x as long in criterion and 1.15x to 1.4x
/// in a fresh process, where ordinary pages took 0.96x to 1.0x the time of fresh `Vec`s
/// (docs/RESULTS.md).
pub struct Pixels(Plane);

impl Pixels {
    /// `n` pixels of unspecified values, for a caller that writes them all.
    pub fn overwritten(n: usize) -> Pixels {
        Pixels(Plane::heap(3 * n))
    }

    /// A copy of `pixels`, made in parallel.
    pub fn copy_of(pixels: &[Vec3]) -> Pixels {
        let mut out = Pixels::overwritten(pixels.len());
        out.par_iter_mut().zip(pixels).for_each(|(o, &p)| *o = p);
        out
    }

    /// Its pixels as an image of `width` x `height` (a copy).
    pub fn to_image(&self, width: u32, height: u32) -> Image {
        Image { width, height, pixels: self.to_vec() }
    }

    /// The floats, three a pixel.
    pub fn floats_mut(&mut self) -> &mut [f32] {
        &mut self.0
    }
}

impl Deref for Pixels {
    type Target = [Vec3];
    fn deref(&self) -> &[Vec3] {
        // Three floats a pixel, from a plane made of whole pixels: the cast cannot fail.
        bytemuck::cast_slice(&self.0)
    }
}

impl DerefMut for Pixels {
    fn deref_mut(&mut self) -> &mut [Vec3] {
        bytemuck::cast_slice_mut(&mut self.0)
    }
}

impl Clone for Pixels {
    fn clone(&self) -> Pixels {
        Pixels::copy_of(self)
    }
}

impl PartialEq for Pixels {
    fn eq(&self, other: &Pixels) -> bool {
        **self == **other
    }
}

impl PartialEq<[Vec3]> for Pixels {
    fn eq(&self, other: &[Vec3]) -> bool {
        **self == *other
    }
}

impl PartialEq<Image> for Pixels {
    fn eq(&self, other: &Image) -> bool {
        **self == other.pixels[..]
    }
}

impl std::fmt::Debug for Pixels {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
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

    #[test]
    fn pixels_are_three_floats_a_pixel_and_copy_whole() {
        let want: Vec<Vec3> = (0..1001).map(|i| Vec3::new(i as f32, -(i as f32), 0.5)).collect();
        let p = Pixels::copy_of(&want);
        assert_eq!(p.len(), want.len());
        assert!(p == *want.as_slice());
        assert_eq!(p.to_image(7, 143).pixels, want);
        let mut q = p.clone();
        q[3] = Vec3::ONE;
        assert!(q != p && q[3] == Vec3::ONE && q.floats_mut()[9..12] == [1.0; 3]);
    }

    #[test]
    fn pixels_too_large_to_keep_are_never_mapped() {
        let n = MAPPED_MIN / (3 * size_of::<f32>()) + 1;
        let mut p = Pixels::overwritten(n);
        assert_eq!(p.len(), n);
        assert!(matches!(p.0 .0, Store::Heap(_)), "a large image in a mapping of its own");
        p[n - 1] = Vec3::X;
        assert_eq!(p[n - 1], Vec3::X);
    }
}
