//! Benchmarks behind the command line: `bench-accel` measures both backends on identical ray
//! sets, side by side in one run, so their ratio means something on a noisy machine.

pub mod features;
pub mod plot;
pub mod rays;

use std::time::Instant;

use rayon::prelude::*;

use crate::accel::{self, bvh::Bvh, Accel, Backend, Ray};
use crate::scene::Scene;
use rays::{RayKind, RaySets};

/// What to measure.
#[derive(Clone, Debug)]
pub struct BenchAccelOptions {
    /// Primary rays to generate (shadow and incoherent rays come from their hits).
    pub rays: usize,
    /// The "all threads" count (the one-thread rows are always measured too).
    pub threads: usize,
    /// Seconds each measurement runs at least.
    pub min_seconds: f64,
    /// Rounds per row; each round measures Embree then the BVH back to back. The medians over
    /// rounds are reported, so one slow moment of a noisy machine does not decide a row.
    pub rounds: usize,
    pub seed: u64,
    /// The BVH's kernels (`None`: the best this CPU runs).
    pub bvh_isa: Option<crate::accel::bvh::simd::Isa>,
}

/// One measured row.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    pub backend: Backend,
    pub rays: RayKind,
    pub threads: usize,
    pub mrays_per_second: f64,
    /// For the BVH rows: the median over rounds of BVH / Embree, each measured back to back.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ratio: Option<f64>,
}

/// The median (the mean of the middle two for an even count).
pub(crate) fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => 0.0,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Everything `bench-accel` measured.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BenchAccelReport {
    pub scene: String,
    pub triangles: usize,
    pub spheres: usize,
    pub ray_counts: [usize; 3],
    /// Build time of each backend (the best of three builds), by backend name.
    pub build_seconds: std::collections::BTreeMap<String, f64>,
    /// Embree's scene settings: a render's of this scene ([`accel::BuildHints::for_scene`]).
    /// Until 2026-12-07 Embree was measured robust at build quality `high` whatever the scene,
    /// which a scene of several shapes renders at `low` (docs/RESULTS.md, "Other scenes").
    pub embree_build: accel::BuildHints,
    /// The BVH's wide tree: nodes, leaves, fill and bytes.
    pub bvh_tree: crate::accel::bvh::wide::WideStats,
    /// The BVH's slab test (`avx512`, `avx2` or `portable`).
    pub bvh_isa: &'static str,
    /// Bytes the BVH holds, exactly ([`Bvh::bytes`]).
    pub bvh_bytes: usize,
    /// How much the process's resident memory grew across one build of each backend (Linux;
    /// absent elsewhere): the only figure there is for Embree, which manages its own memory.
    pub resident_growth_bytes: std::collections::BTreeMap<String, u64>,
    pub rows: Vec<Row>,
}

/// Traces `rays` once on the current rayon pool; returns how many hit (so nothing is optimised
/// away, and so backends can be checked for the same answer count).
pub fn trace_pass<A: Accel>(accel: &A, rays: &[Ray], kind: RayKind) -> usize {
    rays.par_chunks(1024)
        .map(|chunk| match kind {
            RayKind::Shadow => chunk.iter().filter(|r| accel.occluded(r)).count(),
            _ => chunk.iter().filter(|r| accel.intersect(r).is_some()).count(),
        })
        .sum()
}

/// Millions of rays per second over passes lasting at least `min_seconds` in all.
fn rate<A: Accel>(accel: &A, rays: &[Ray], kind: RayKind, min_seconds: f64) -> f64 {
    if rays.is_empty() {
        return 0.0;
    }
    trace_pass(accel, rays, kind); // warm caches
    let start = Instant::now();
    let mut traced = 0usize;
    loop {
        trace_pass(accel, rays, kind);
        traced += rays.len();
        let t = start.elapsed().as_secs_f64();
        if t >= min_seconds {
            return traced as f64 / t / 1e6;
        }
    }
}

fn best_of<T>(n: usize, mut f: impl FnMut() -> (T, f64)) -> (T, f64) {
    let (mut keep, mut best) = f();
    for _ in 1..n {
        let (v, t) = f();
        if t < best {
            best = t;
            keep = v;
        }
    }
    (keep, best)
}

/// Runs the benchmark. `progress` is called after each measurement with (done, total).
pub fn bench_accel(
    scene: &Scene,
    options: &BenchAccelOptions,
    progress: &dyn Fn(usize, usize),
) -> Result<BenchAccelReport, accel::AccelError> {
    // Embree built as a render of the scene builds it.
    let hints = accel::BuildHints::of(scene);
    // Memory first, one fresh build of each backend, each dropped before the next.
    let mut resident_growth_bytes = std::collections::BTreeMap::new();
    let growth = [
        (Backend::Embree, resident_growth(|| accel::build_embree_with(scene, None, hints))?),
        (Backend::Bvh, resident_growth(|| Bvh::new(scene))?),
    ];
    for (backend, grew) in growth {
        if let Some(bytes) = grew {
            resident_growth_bytes.insert(backend.to_string(), bytes);
        }
    }

    let (embree, embree_build) = best_of(3, || {
        let start = Instant::now();
        let e = accel::build_embree_with(scene, None, hints);
        (e, start.elapsed().as_secs_f64())
    });
    let embree = embree?;
    let (bvh, bvh_build) = best_of(3, || {
        let start = Instant::now();
        let b = Bvh::new(scene);
        (b, start.elapsed().as_secs_f64())
    });
    let bvh = match options.bvh_isa {
        Some(isa) => bvh?.with_isa(isa),
        None => bvh?,
    };

    let sets = RaySets::generate(scene, &embree, options.rays, options.seed);
    let mut thread_counts = vec![1];
    if options.threads > 1 {
        thread_counts.push(options.threads);
    }
    let total = RayKind::ALL.len() * thread_counts.len();
    let mut rows = Vec::new();
    let mut done = 0;
    for kind in RayKind::ALL {
        let rays = sets.get(kind);
        for &threads in &thread_counts {
            let pool = accel::thread_pool(threads)?;
            let (mut e, mut b, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
            pool.install(|| {
                for _ in 0..options.rounds.max(1) {
                    let re = rate(&embree, rays, kind, options.min_seconds);
                    let rb = rate(&bvh, rays, kind, options.min_seconds);
                    e.push(re);
                    b.push(rb);
                    ratio.push(rb / re.max(1e-12));
                }
            });
            let row = |backend, mrays_per_second, ratio| Row {
                backend,
                rays: kind,
                threads,
                mrays_per_second,
                ratio,
            };
            rows.push(row(Backend::Embree, median(e), None));
            rows.push(row(Backend::Bvh, median(b), Some(median(ratio))));
            done += 1;
            progress(done, total);
        }
    }
    let spheres =
        scene.shapes.iter().filter(|s| matches!(s.geometry, crate::scene::Geometry::Sphere { .. })).count();
    Ok(BenchAccelReport {
        scene: scene.path.display().to_string(),
        triangles: scene.triangle_count(),
        spheres,
        ray_counts: [sets.primary.len(), sets.shadow.len(), sets.incoherent.len()],
        build_seconds: [(Backend::Embree.to_string(), embree_build), (Backend::Bvh.to_string(), bvh_build)]
            .into_iter()
            .collect(),
        embree_build: hints,
        bvh_tree: bvh.stats(),
        bvh_isa: bvh.isa().name(),
        bvh_bytes: bvh.bytes(),
        resident_growth_bytes,
        rows,
    })
}

impl BenchAccelReport {
    /// The report as a plain-text table, with the BVH/Embree ratio on each row.
    pub fn table(&self) -> String {
        let mut out = format!(
            "{}: {} triangles, {} spheres; rays: {} primary, {} shadow, {} incoherent\n",
            self.scene,
            self.triangles,
            self.spheres,
            self.ray_counts[0],
            self.ray_counts[1],
            self.ray_counts[2]
        );
        let build = |b: Backend| self.build_seconds.get(&b.to_string()).copied().unwrap_or(0.0);
        let (be, bb) = (build(Backend::Embree), build(Backend::Bvh));
        out += &format!(
            "build        embree {:>9.4} s   bvh {:>9.4} s   bvh/embree time {:>5.2}x   (embree {}, quality {}, as a render builds it)\n",
            be,
            bb,
            bb / be.max(1e-12),
            if self.embree_build.robust { "robust" } else { "not robust" },
            self.embree_build.quality.name()
        );
        let t = &self.bvh_tree;
        out += &format!(
            "bvh tree     {} nodes ({:.2} children each, depth {}), {} leaves ({:.2} triangles each), {:.1} bytes per triangle, {} slab test; SAH {:.3} (nodes {:.3}, leaves {:.3}, as Embree's statistics count it)\n",
            t.nodes,
            t.mean_children,
            t.depth,
            t.leaves,
            t.mean_leaf_triangles,
            t.bytes as f64 / self.triangles.max(1) as f64,
            self.bvh_isa,
            t.sah_nodes + t.sah_leaves,
            t.sah_nodes,
            t.sah_leaves
        );
        let mb = |b: u64| b as f64 / 1e6;
        let per = |b: u64| b as f64 / self.triangles.max(1) as f64;
        let resident = |backend: Backend| {
            self.resident_growth_bytes.get(&backend.to_string()).map_or("not measured".to_string(), |&b| {
                format!("{:.1} MB resident growth ({:.1} B/triangle)", mb(b), per(b))
            })
        };
        out += &format!(
            "memory       embree {}\n             bvh {:.1} MB held exactly ({:.1} B/triangle), {}\n",
            resident(Backend::Embree),
            mb(self.bvh_bytes as u64),
            per(self.bvh_bytes as u64),
            resident(Backend::Bvh)
        );
        out += "rays        threads   embree Mrays/s   bvh Mrays/s   bvh/embree (median of rounds)\n";
        for pair in self.rows.chunks(2) {
            if let [e, b] = pair {
                out += &format!(
                    "{:<11} {:>7}   {:>14.2}   {:>11.2}   {:>9.2}x\n",
                    e.rays.name(),
                    e.threads,
                    e.mrays_per_second,
                    b.mrays_per_second,
                    b.ratio.unwrap_or(b.mrays_per_second / e.mrays_per_second.max(1e-12))
                );
            }
        }
        out
    }
}

/// How much the process's resident memory grew across `build` (what it built is dropped after),
/// where the system reports resident memory.
fn resident_growth<T, E: Into<accel::AccelError>>(
    build: impl FnOnce() -> Result<T, E>,
) -> Result<Option<u64>, accel::AccelError> {
    let before = resident_bytes();
    let built = build().map_err(Into::into)?;
    let after = resident_bytes();
    drop(built);
    Ok(before.zip(after).map(|(a, b)| b.saturating_sub(a)))
}

/// The process's resident memory (VmRSS of /proc/self/status), where there is one.
fn resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmRSS:"))?;
    let kb: u64 = line.trim_start_matches("VmRSS:").trim().trim_end_matches("kB").trim().parse().ok()?;
    Some(kb * 1024)
}

/// One Embree setting measured by [`bench_embree_settings`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct SettingsRow {
    pub settings: accel::BuildHints,
    /// The best of three builds.
    pub build_seconds: f64,
    /// Millions of rays per second for primary, shadow and incoherent rays (median of rounds).
    pub mrays_per_second: [f64; 3],
    /// For each ray set, the median over rounds of this setting's rate over the default's
    /// (robust, high), measured back to back.
    pub speed_vs_default: [f64; 3],
    /// Rays of all three sets whose answer (hit or miss, and which primitive) differs from the
    /// default's.
    pub answers_changed: usize,
}

/// Measures every Embree scene setting (robust or not, each build quality) on the same ray
/// sets, each round measuring the default and then the others back to back on all threads.
pub fn bench_embree_settings(
    scene: &Scene,
    options: &BenchAccelOptions,
    progress: &dyn Fn(usize, usize),
) -> Result<Vec<SettingsRow>, accel::AccelError> {
    use accel::{BuildHints, BuildQuality};
    let mut all = vec![BuildHints::default()];
    for robust in [true, false] {
        for quality in BuildQuality::ALL {
            let s = BuildHints { robust, quality };
            if s != BuildHints::default() {
                all.push(s);
            }
        }
    }
    let mut built = Vec::new();
    for &settings in &all {
        let (e, seconds) = best_of(3, || {
            let start = Instant::now();
            let e = accel::build_embree_with(scene, None, settings);
            (e, start.elapsed().as_secs_f64())
        });
        built.push((e?, seconds));
    }
    let sets = RaySets::generate(scene, &built[0].0, options.rays, options.seed);
    let answers = |a: &accel::embree::CommittedScene| -> Vec<Option<(u32, u32)>> {
        RayKind::ALL
            .iter()
            .flat_map(|&kind| {
                sets.get(kind).iter().map(move |r| match kind {
                    RayKind::Shadow => a.occluded(r).then_some((0, 0)),
                    _ => a.intersect(r).map(|h| (h.shape, h.prim)),
                })
            })
            .collect()
    };
    let reference = answers(&built[0].0);
    let pool = accel::thread_pool(options.threads)?;
    let total = options.rounds.max(1) * RayKind::ALL.len();
    let mut rates = vec![[const { Vec::new() }; 3]; all.len()];
    let mut ratios = vec![[const { Vec::new() }; 3]; all.len()];
    let mut done = 0;
    for _ in 0..options.rounds.max(1) {
        for (k, &kind) in RayKind::ALL.iter().enumerate() {
            let rays = sets.get(kind);
            let measured: Vec<f64> = pool
                .install(|| built.iter().map(|(e, _)| rate(e, rays, kind, options.min_seconds)).collect());
            for (i, r) in measured.iter().enumerate() {
                rates[i][k].push(*r);
                ratios[i][k].push(r / measured[0].max(1e-12));
            }
            done += 1;
            progress(done, total);
        }
    }
    Ok(all
        .iter()
        .zip(&built)
        .enumerate()
        .map(|(i, (&settings, (e, build_seconds)))| SettingsRow {
            settings,
            build_seconds: *build_seconds,
            mrays_per_second: std::array::from_fn(|k| median(rates[i][k].clone())),
            speed_vs_default: std::array::from_fn(|k| median(ratios[i][k].clone())),
            answers_changed: answers(e).iter().zip(&reference).filter(|(a, b)| a != b).count(),
        })
        .collect())
}

/// The settings rows as a plain-text table.
pub fn settings_table(rows: &[SettingsRow]) -> String {
    let mut out = String::from(
        "robust  quality   build s   primary Mrays/s   shadow Mrays/s   incoherent Mrays/s   answers changed\n",
    );
    for r in rows {
        let cell = |k: usize| format!("{:.2} ({:.2}x)", r.mrays_per_second[k], r.speed_vs_default[k]);
        out += &format!(
            "{:<7} {:<8} {:>8.4}   {:>15}   {:>14}   {:>18}   {:>15}\n",
            if r.settings.robust { "yes" } else { "no" },
            r.settings.quality.name(),
            r.build_seconds,
            cell(0),
            cell(1),
            cell(2),
            r.answers_changed
        );
    }
    out
}
