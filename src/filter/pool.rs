//! The filter's working planes, kept between calls. A 256x256 `--denoise` works in about 16 MB of
//! planes; freshly allocated, every 4 KB page of them is a page fault when first written and
//! an unmapping when freed, which took about a third of a warm call (docs/RESULTS.md, the
//! denoising section). A plane taken here reuses one that an earlier call, or an earlier step
//! of this one, gave back; planes are given back when dropped, and the pool keeps up to
//! [`KEEP_BYTES`] of them for as long as the process runs.
//!
//! Planes too large for that (from [`MAPPED_MIN`]: a 4K image's, even of one float a pixel)
//! are mapped in transparent huge pages, one fault for 2 MB rather than for 4 KB (but
//! [`Pixels`], which stay in ordinary pages), and are kept only for [`KEEP_LARGE`] after each
//! was given back, then freed by a thread of the pool's own: a call that follows within that
//! time (the next frame of a sequence, criterion's next iteration) takes them again without a
//! page fault, while a process that filtered one 4K image does not keep its gigabytes. At 4K,
//! fresh pages took about an eighth of a warm call (docs/RESULTS.md).

use std::ops::{Deref, DerefMut};
use std::sync::{Condvar, Mutex, OnceLock};
use std::time::{Duration, Instant};

use glam::Vec3;
use rayon::prelude::*;

use crate::film::Image;

/// The most the pool keeps between uses: a 512x512 `--denoise`'s planes, about 80 MB.
pub const KEEP_BYTES: usize = 96 << 20;

/// How long a plane of [`MAPPED_MIN`] or more is kept after it was given back.
pub const KEEP_LARGE: Duration = Duration::from_secs(3);

/// Planes given back and not yet taken again: the small ones and the bytes they hold, and the
/// large ones with the moment each was given back.
struct Pool {
    small: Vec<Vec<f32>>,
    bytes: usize,
    large: Vec<(Store, Instant)>,
}

static POOL: Mutex<Pool> = Mutex::new(Pool { small: Vec::new(), bytes: 0, large: Vec::new() });
/// Wakes the thread that frees the large planes ([`free_large_planes`]) when one is given back.
static GIVEN_BACK: Condvar = Condvar::new();
/// Whether that thread runs; without it, large planes are freed when given back.
static FREEING: OnceLock<bool> = OnceLock::new();

fn lock() -> std::sync::MutexGuard<'static, Pool> {
    // A poisoned lock only means another thread panicked while holding it; the planes in it
    // are whole either way.
    POOL.lock().unwrap_or_else(|e| e.into_inner())
}

/// The pool's thread: frees each large plane [`KEEP_LARGE`] after it was given back, sleeping
/// until the next one is due or one is given back.
fn free_large_planes() {
    let mut pool = lock();
    loop {
        let now = Instant::now();
        let (due, kept): (Vec<_>, Vec<_>) =
            pool.large.drain(..).partition(|(_, at)| now.duration_since(*at) >= KEEP_LARGE);
        pool.large = kept;
        let next = pool.large.iter().map(|(_, at)| *at + KEEP_LARGE).min();
        if !due.is_empty() {
            // Unmapped outside the lock.
            drop(pool);
            drop(due);
            pool = lock();
            continue;
        }
        pool = match next {
            Some(at) => {
                GIVEN_BACK
                    .wait_timeout(pool, at.saturating_duration_since(now))
                    .unwrap_or_else(|e| e.into_inner())
                    .0
            }
            None => GIVEN_BACK.wait(pool).unwrap_or_else(|e| e.into_inner()),
        };
    }
}

/// Whether large planes are kept: the freeing thread is running (started on first use).
fn keeps_large() -> bool {
    *FREEING.get_or_init(|| {
        std::thread::Builder::new().name("lightsplit-pool".into()).spawn(free_large_planes).is_ok()
    })
}

/// A plane of `f32` taken from the pool (or allocated when none there is large enough), zeroed
/// or of unspecified values as asked, and given back to the pool when dropped.
pub struct Plane {
    store: Store,
    /// The floats in use: a plane taken again may be longer than asked for.
    len: usize,
}

enum Store {
    Heap(Vec<f32>),
    /// A large plane, in huge pages where the system gives them.
    Mapped(crate::accel::bvh::pages::Pages<f32>),
}

impl Store {
    fn floats(&self) -> &[f32] {
        match self {
            Store::Heap(v) => v,
            Store::Mapped(p) => p,
        }
    }

    fn floats_mut(&mut self) -> &mut [f32] {
        match self {
            Store::Heap(v) => v,
            Store::Mapped(p) => p,
        }
    }
}

/// Planes of at least this many bytes are kept only for [`KEEP_LARGE`], and get huge pages
/// (but [`Pixels`]): a 4K image's plane of one float a pixel (33.2 MB) and more.
const MAPPED_MIN: usize = 16 << 20;

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

    /// [`Plane::overwritten`], in ordinary memory whatever its size: a large plane is an
    /// allocation of the heap, never a mapping of its own.
    fn heap(n: usize) -> Plane {
        Plane::of_in(n, false, false)
    }

    fn of(n: usize, zeroed: bool) -> Plane {
        Plane::of_in(n, zeroed, true)
    }

    /// `n` floats, zeroed or not; from [`MAPPED_MIN`] `mapped` in huge pages.
    fn of_in(n: usize, zeroed: bool, mapped: bool) -> Plane {
        if n * size_of::<f32>() >= MAPPED_MIN {
            let store = match take_large(n, mapped) {
                Some(mut store) => {
                    if zeroed {
                        store.floats_mut()[..n].fill(0.0);
                    }
                    store
                }
                // New memory from the system is zero already.
                None if mapped => Store::Mapped(crate::accel::bvh::pages::Pages::zeroed(n)),
                None => Store::Heap(vec![0.0; n]),
            };
            return Plane { store, len: n };
        }
        match take(n) {
            Some(mut v) => {
                // Zeroed: every value written again; else only those past the old length.
                v.truncate(if zeroed { 0 } else { n });
                v.resize(n, 0.0);
                Plane { store: Store::Heap(v), len: n }
            }
            // New memory from the system is zero already: its pages are touched (and faulted
            // in) only by whichever threads write them first, not all here, by this one.
            None => Plane { store: Store::Heap(vec![0.0; n]), len: n },
        }
    }
}

/// The smallest pooled vector that holds `n` floats without growing (its contents
/// unspecified).
fn take(n: usize) -> Option<Vec<f32>> {
    let mut pool = lock();
    let best =
        pool.small.iter().enumerate().filter(|(_, v)| v.capacity() >= n).min_by_key(|(_, v)| v.capacity());
    let best = best?.0;
    let v = pool.small.swap_remove(best);
    pool.bytes -= v.capacity() * size_of::<f32>();
    Some(v)
}

/// The smallest large plane kept that holds `n` floats, mapped or on the heap as asked, and
/// no more than a quarter larger: a request does not hold a plane that a larger one would
/// need, which would then be allocated afresh beside it.
fn take_large(n: usize, mapped: bool) -> Option<Store> {
    let mut pool = lock();
    let fits = |len: usize| len >= n && len <= n + n / 4;
    let best = (pool.large.iter().enumerate())
        .filter(|(_, (s, _))| matches!(s, Store::Mapped(_)) == mapped && fits(s.floats().len()))
        .min_by_key(|(_, (s, _))| s.floats().len());
    let best = best?.0;
    Some(pool.large.swap_remove(best).0)
}

impl Drop for Plane {
    fn drop(&mut self) {
        let store = std::mem::replace(&mut self.store, Store::Heap(Vec::new()));
        let size = match &store {
            Store::Heap(v) => v.capacity(),
            Store::Mapped(p) => p.len(),
        } * size_of::<f32>();
        if size == 0 {
            return;
        }
        if size >= MAPPED_MIN {
            if keeps_large() {
                lock().large.push((store, Instant::now()));
                GIVEN_BACK.notify_all();
            }
            return;
        }
        let Store::Heap(v) = store else { return };
        let mut pool = lock();
        if pool.bytes + size <= KEEP_BYTES {
            pool.bytes += size;
            pool.small.push(v);
        }
    }
}

impl Deref for Plane {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        &self.store.floats()[..self.len]
    }
}

impl DerefMut for Plane {
    fn deref_mut(&mut self) -> &mut [f32] {
        let len = self.len;
        &mut self.store.floats_mut()[..len]
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

    /// Held by every test that takes or gives back large planes, so that no other test takes
    /// the plane one of them gave back.
    static LARGE: Mutex<()> = Mutex::new(());

    fn large_lock() -> std::sync::MutexGuard<'static, ()> {
        LARGE.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Whether the pool keeps the large plane whose floats start at `at`.
    fn kept(at: *const f32) -> bool {
        lock().large.iter().any(|(s, _)| std::ptr::eq(s.floats().as_ptr(), at))
    }

    #[test]
    fn a_large_plane_is_zeros_and_holds_its_values() {
        let _large = large_lock();
        let n = MAPPED_MIN / size_of::<f32>() + 5;
        let mut p = Plane::zeroed(n);
        assert_eq!(p.len(), n);
        assert!(p.iter().all(|&v| v == 0.0));
        p.iter_mut().enumerate().for_each(|(i, v)| *v = i as f32);
        assert!(p.iter().enumerate().all(|(i, &v)| v == i as f32));
    }

    #[test]
    fn a_large_plane_taken_again_has_its_length_and_zeros_when_asked() {
        let _large = large_lock();
        // Large planes of several lengths, written and given back, then taken again: each has
        // the length asked for, and is all zeros when asked to be, whichever plane it reuses.
        let n = MAPPED_MIN / size_of::<f32>() + 1000;
        for (m, mapped) in [(n + 77, true), (n, true), (n + 9, false), (n, false)] {
            let mut p = Plane::of_in(m, false, mapped);
            assert_eq!(p.len(), m);
            p.iter_mut().for_each(|v| *v = 3.0);
        }
        for (m, mapped) in [(n + 5, true), (n + 3, false), (n, true)] {
            let p = Plane::of_in(m, true, mapped);
            assert_eq!(p.len(), m);
            assert!(p.iter().all(|&v| v == 0.0), "a large plane of {m} is not all zeros");
        }
    }

    #[test]
    fn a_large_plane_is_taken_again_then_freed_after_its_time() {
        let _large = large_lock();
        assert!(keeps_large(), "the pool's thread did not start");
        let n = 3 * MAPPED_MIN / size_of::<f32>() + 11;
        let p = Plane::overwritten(n);
        let at = p.as_ptr();
        drop(p);
        // Taken again at once: the same memory, its values left as they were.
        let p = Plane::overwritten(n - 7);
        assert!(std::ptr::eq(p.as_ptr(), at), "a large plane given back was not taken again");
        // A request of twice its size does not take it, nor one it is far too large for.
        drop(p);
        for m in [2 * n, n / 2] {
            let q = Plane::overwritten(m);
            assert!(!std::ptr::eq(q.as_ptr(), at), "a plane of {n} taken for {m}");
        }
        std::thread::sleep(KEEP_LARGE / 3);
        assert!(kept(at), "a large plane freed before its time");
        // Freed once its time has passed, with a second of leeway for a busy machine.
        std::thread::sleep(KEEP_LARGE + Duration::from_secs(1));
        assert!(!kept(at), "a large plane kept past its time");
    }

    #[test]
    fn the_pool_keeps_no_more_than_its_limit() {
        // Planes larger than the limit together: dropping them all leaves at most the limit.
        let n = MAPPED_MIN / size_of::<f32>() - 1;
        let count = KEEP_BYTES / MAPPED_MIN + 2;
        let planes: Vec<Plane> = (0..count).map(|_| Plane::zeroed(n)).collect();
        drop(planes);
        // (Other tests take and give back planes meanwhile; the limit holds at every moment.)
        let bytes = lock().bytes;
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
    fn large_pixels_are_never_mapped() {
        let _large = large_lock();
        let n = MAPPED_MIN / (3 * size_of::<f32>()) + 1;
        let mut p = Pixels::overwritten(n);
        assert_eq!(p.len(), n);
        assert!(matches!(p.0.store, Store::Heap(_)), "a large image in a mapping of its own");
        p[n - 1] = Vec3::X;
        assert_eq!(p[n - 1], Vec3::X);
    }
}
