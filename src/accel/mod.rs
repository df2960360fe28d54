//! The one interface the renderer traces rays through. The integrator is generic over [`Accel`]
//! (monomorphised, no dynamic dispatch per ray) and never knows which backend it has.

pub mod bvh;
pub mod embree;

use glam::Vec3;

/// A ray from `origin` along `dir` (not necessarily unit length), valid for `t` in `[0, t_max]`.
/// Secondary rays get their origin offset off the surface instead of a `t_min`.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    pub t_max: f32,
}

impl Ray {
    /// A ray with no far limit.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Ray { origin, dir, t_max: f32::INFINITY }
    }

    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// A closest hit, in the same convention on every backend: `shape` is the scene's shape index,
/// `prim` the triangle index within that shape (0 for a sphere), and `(u, v)` the barycentric
/// weights of the triangle's second and third vertices (unused for spheres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub shape: u32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// A ray tracing backend over a committed, immutable scene. Queries are safe from many threads.
pub trait Accel: Send + Sync {
    /// The closest hit along `ray` within `[0, ray.t_max]`, if any.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;
    /// Whether anything lies along `ray` within `[0, ray.t_max]` (a shadow ray: any hit stops it).
    fn occluded(&self, ray: &Ray) -> bool;
    /// The closest hits of coherent `rays` (starting together, pointing nearly the same way: a
    /// pixel's camera rays), `hits[i]` for `rays[i]`; the same hits as [`Accel::intersect`] up
    /// to float rounding. A backend may trace them as packets; by default, one by one.
    fn intersect_coherent(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        for (ray, hit) in rays.iter().zip(hits.iter_mut()) {
            *hit = self.intersect(ray);
        }
    }
}

/// A failure to set up ray tracing: a backend that cannot build, or worker threads that cannot
/// start.
#[derive(Debug, thiserror::Error)]
pub enum AccelError {
    #[error(transparent)]
    Embree(#[from] embree::EmbreeError),
    #[error(transparent)]
    Bvh(#[from] bvh::TooLarge),
    #[error("cannot start {0} worker threads: {1}")]
    Threads(usize, String),
}

/// A rayon pool of `n` threads.
pub fn thread_pool(n: usize) -> Result<rayon::ThreadPool, AccelError> {
    rayon::ThreadPoolBuilder::new().num_threads(n).build().map_err(|e| AccelError::Threads(n, e.to_string()))
}

/// Makes the calling thread one of the global pool's threads (rayon's `use_current_thread`):
/// for a program's main thread, called first, before anything runs in parallel. A parallel
/// step the caller starts then runs in the pool as a step within it does: the caller takes
/// part and the other threads steal from it. From outside the pool, each step was handed over
/// while the caller slept, a wake-up of both sides per step: a 256x256 `--denoise`, about 27
/// such steps, took 1.1x as long from outside. At 3840x2160, where a step is long, criterion
/// measured the reverse, 1.045x as long in the pool (docs/RESULTS.md, "The main thread in the
/// pool"). The pool keeps its size (one thread a core, the caller among them). Once a global
/// pool runs, later calls leave it as it is: it stays a pool, only the hand-over costs more.
pub fn join_global_pool() {
    // Its one error: a global pool already built (or no thread to start, which leaves rayon
    // to start the pool when first used, as without this call).
    let _ = rayon::ThreadPoolBuilder::new().use_current_thread().build_global();
}

/// Runs `op` on one of the global pool's threads while the caller waits, and returns what it
/// returns: the parallel steps `op` starts then begin inside the pool, one hand-over for the
/// whole call instead of one a step ([`join_global_pool`]). For callers that cannot join the
/// pool, the Python module's threads. From inside the pool, `op` runs where it is.
pub fn in_pool<R: Send>(op: impl FnOnce() -> R + Send) -> R {
    rayon::join(op, || ()).0
}

/// The backends a render can choose at run time.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Backend {
    /// Intel Embree through FFI (the default).
    #[default]
    Embree,
    /// lightsplit's own BVH, in pure Rust.
    Bvh,
}

impl Backend {
    /// The name on the command line, in `--json` and in `converge`'s results.
    pub fn name(self) -> &'static str {
        match self {
            Backend::Embree => "embree",
            Backend::Bvh => "bvh",
        }
    }

    /// Builds this backend over `scene` (`threads` limits Embree's build threads; `hints` are
    /// what the scene asks of the build) and hands it to `u`: the one place a backend is chosen,
    /// so code generic over [`Accel`] is compiled once for each.
    pub fn build<U: UseAccel>(
        self,
        scene: &crate::scene::Scene,
        threads: Option<usize>,
        hints: BuildHints,
        u: U,
    ) -> Result<U::Output, AccelError> {
        Ok(match self {
            Backend::Embree => u.with(&build_embree_with(scene, threads, hints)?),
            Backend::Bvh => u.with(&bvh::Bvh::new(scene)?),
        })
    }
}

/// What to do with an accelerator, whichever backend it is ([`Backend::build`]).
pub trait UseAccel {
    type Output;
    fn with<A: Accel>(self, accel: &A) -> Self::Output;
}

impl std::fmt::Display for Backend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Rays in one of the packets [`Accel::intersect_coherent`] traces together (camera rays, in
/// passes of this many samples a pixel).
pub const PACKET: usize = 8;

/// How hard an accelerator's build works for a faster tree.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BuildQuality {
    Low,
    Medium,
    /// Spatial splits: the slowest build, the fastest traversal.
    #[default]
    High,
}

impl BuildQuality {
    pub const ALL: [BuildQuality; 3] = [BuildQuality::Low, BuildQuality::Medium, BuildQuality::High];

    pub fn name(self) -> &'static str {
        match self {
            BuildQuality::Low => "low",
            BuildQuality::Medium => "medium",
            BuildQuality::High => "high",
        }
    }
}

/// What a scene asks of an accelerator's build, passed by the renderer without knowing which
/// backend takes it: Embree reads both hints; the BVH's test is always watertight and it builds
/// one way.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct BuildHints {
    /// A watertight triangle test (no ray slips through a shared edge) and no traversal
    /// shortcuts that lose accuracy: Embree's `RTC_SCENE_FLAG_ROBUST`.
    pub robust: bool,
    pub quality: BuildQuality,
}

impl Default for BuildHints {
    fn default() -> Self {
        BuildHints { robust: true, quality: BuildQuality::High }
    }
}

impl BuildHints {
    /// The build a scene needs, from `bench-accel --embree-settings` over `scenes/`: the robust
    /// (watertight) mode whenever there are triangles (without it rays slipped through shared
    /// edges of `paper-sky.toml` and the terrain), and none for spheres alone; the two-level
    /// build (`low`) for a scene of several shapes, which measured 1.0x to 1.9x the rays per
    /// second of `high` there with the same answers; `high` for one shape, where it measured
    /// the same or slightly better.
    pub fn for_scene(analysis: &crate::scene::analysis::Analysis) -> BuildHints {
        BuildHints {
            robust: analysis.triangles > 0,
            quality: if analysis.shapes > 1 { BuildQuality::Low } else { BuildQuality::High },
        }
    }

    /// [`Self::for_scene`] from the scene itself, for a caller without its analysis.
    pub fn of(scene: &crate::scene::Scene) -> BuildHints {
        BuildHints::for_scene(&crate::scene::analysis::Analysis::of(scene))
    }
}

/// Builds Embree's BVH over every shape of `scene` with the settings a render of it uses
/// ([`BuildHints::for_scene`]); geometry IDs are shape indices. Meshes are shared with Embree,
/// not copied. `threads` limits Embree's build threads.
pub fn build_embree(
    scene: &crate::scene::Scene,
    threads: Option<usize>,
) -> Result<embree::CommittedScene, embree::EmbreeError> {
    build_embree_with(scene, threads, BuildHints::of(scene))
}

/// The environment variable whose value is appended to Embree's device configuration, e.g.
/// `verbose=1` to print the ISA and the BVH and intersector Embree picked, or
/// `frequency_level=simd128`.
pub const EMBREE_CONFIG_VAR: &str = "LIGHTSPLIT_EMBREE_CONFIG";

/// Embree's device configuration: the build threads, then what [`EMBREE_CONFIG_VAR`] adds.
fn device_config(threads: Option<usize>) -> String {
    let mut config = threads.map(|n| format!("threads={n}")).unwrap_or_default();
    if let Some(extra) = std::env::var_os(EMBREE_CONFIG_VAR) {
        if !config.is_empty() {
            config.push(',');
        }
        config.push_str(&extra.to_string_lossy());
    }
    config
}

/// [`build_embree`] with these scene flags and build quality.
pub fn build_embree_with(
    scene: &crate::scene::Scene,
    threads: Option<usize>,
    settings: BuildHints,
) -> Result<embree::CommittedScene, embree::EmbreeError> {
    use crate::scene::Geometry;
    let config = device_config(threads);
    let device = embree::Device::with_config(&config)?;
    let mut builder = device.scene_with(settings)?;
    // Only the meshes with a cut-out (or whose instances have one) get a filter function.
    let cutouts = crate::scene::cutout::Cutouts::new(scene).map(std::sync::Arc::new);
    let cut_arrays: std::collections::HashSet<(usize, usize)> = match &cutouts {
        None => Default::default(),
        Some(c) => scene
            .shapes
            .iter()
            .enumerate()
            .filter(|(id, _)| c.cuts(*id as u32))
            .filter_map(|(_, s)| match &s.geometry {
                Geometry::Triangles(mesh) if mesh.instance.is_some() => Some(mesh.arrays()),
                _ => None,
            })
            .collect(),
    };
    // One scene per shared mesh, instanced by every shape that places it.
    let mut prototypes: std::collections::HashMap<(usize, usize), std::sync::Arc<embree::CommittedScene>> =
        std::collections::HashMap::new();
    for (id, shape) in scene.shapes.iter().enumerate() {
        match &shape.geometry {
            Geometry::Sphere { center, radius } => {
                builder.add_spheres(id as u32, &[center.extend(*radius)])?;
            }
            Geometry::Triangles(mesh) => match &mesh.instance {
                None => match &cutouts {
                    Some(c) if c.cuts(id as u32) => builder.add_cut_triangles(
                        id as u32,
                        mesh.positions.clone(),
                        mesh.indices.clone(),
                        c,
                    )?,
                    _ => builder.add_triangles(id as u32, mesh.positions.clone(), mesh.indices.clone())?,
                },
                Some(instance) => {
                    let prototype = match prototypes.get(&mesh.arrays()) {
                        Some(p) => p.clone(),
                        None => {
                            let mut one = device.scene_with(settings)?;
                            match &cutouts {
                                Some(c) if cut_arrays.contains(&mesh.arrays()) => {
                                    one.add_cut_triangles(0, mesh.positions.clone(), mesh.indices.clone(), c)?
                                }
                                _ => one.add_triangles(0, mesh.positions.clone(), mesh.indices.clone())?,
                            }
                            let p = std::sync::Arc::new(one.commit()?);
                            prototypes.insert(mesh.arrays(), p.clone());
                            p
                        }
                    };
                    builder.add_instance(id as u32, &prototype, instance.to_world)?;
                }
            },
        }
    }
    builder.commit()
}

#[cfg(test)]
mod tests {
    use rayon::prelude::*;

    /// `in_pool` from outside the pool runs on one of its threads, from inside where it is.
    #[test]
    fn in_pool_runs_on_a_pool_thread_or_where_it_is() {
        use super::in_pool;
        // From a thread of no pool: on one of the global pool's, with the value returned.
        let outside = std::thread::spawn(|| in_pool(|| (rayon::current_thread_index(), 7))).join();
        let Ok((index, value)) = outside else { panic!("in_pool panicked") };
        assert!(index.is_some(), "not run on a pool thread");
        assert_eq!(value, 7);
        // From inside the pool: on the caller's own thread.
        let (here, there) =
            rayon::scope(|_| (std::thread::current().id(), in_pool(|| std::thread::current().id())));
        assert_eq!(here, there);
    }

    /// The calling thread becomes the global pool's thread 0, the pool one thread a core. Run in
    /// a process of its own (this test binary again, with this test alone), since in the test
    /// process other tests may have started the global pool first.
    #[test]
    fn the_calling_thread_joins_the_global_pool() {
        const CHILD: &str = "LIGHTSPLIT_TEST_POOL_CHILD";
        if std::env::var_os(CHILD).is_some() {
            assert_eq!(rayon::current_thread_index(), None);
            super::join_global_pool();
            assert_eq!(rayon::current_thread_index(), Some(0));
            let cores = std::thread::available_parallelism().map_or(1, usize::from);
            assert_eq!(rayon::current_num_threads(), cores);
            // A parallel step from this thread runs on the pool's threads, this one among them.
            let mut on: Vec<Option<usize>> = vec![None; 64];
            on.par_iter_mut().for_each(|t| *t = rayon::current_thread_index());
            assert!(on.iter().all(|t| t.is_some_and(|i| i < cores)));
            return;
        }
        let exe = std::env::current_exe().expect("the test binary");
        let name = "accel::tests::the_calling_thread_joins_the_global_pool";
        let out = std::process::Command::new(exe)
            .args(["--exact", name, "--test-threads", "1"])
            .env(CHILD, "1")
            .output()
            .expect("the test binary runs");
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{stdout}{}", String::from_utf8_lossy(&out.stderr));
        // The child ran this test, not none.
        assert!(stdout.contains("1 passed"), "{stdout}");
    }
}
