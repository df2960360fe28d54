//! `converge`: run time against error, the paper's Figures 5 and 6 for any scene. Each sample
//! count is rendered once per seed, and that render is filtered with every setting (render
//! once, filter many times), render and filter timed apart; every row is appended to
//! `results.csv` as soon as it is known, so a run stopped half way keeps its rows and the same
//! command goes on from there.

pub mod claims;
pub mod plot;
pub mod summary;

use std::collections::HashSet;
use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::film::{self, Image};
use crate::filter::{composite, EdgeStops, Method, Target};
use crate::metrics;
use crate::part::RunKey;
use crate::render::sampler::SamplerKind;
use crate::render::{self, RenderOptions};
use crate::scene::Scene;

/// Edge-aware filtering in a run: off, the paper's object stop, or that and the coverage stop
/// (mixed border pixels left alone).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "cli", derive(clap::ValueEnum))]
pub enum Edge {
    Off,
    On,
    Pure,
}

impl Edge {
    /// The `edge_aware` column: `false`, `true` or `pure`.
    pub fn csv(self) -> &'static str {
        match self {
            Edge::Off => "false",
            Edge::On => "true",
            Edge::Pure => "pure",
        }
    }

    pub fn parse(s: &str) -> Option<Edge> {
        match s {
            "false" | "off" => Some(Edge::Off),
            "true" | "on" => Some(Edge::On),
            "pure" => Some(Edge::Pure),
            _ => None,
        }
    }

    fn label(self) -> &'static str {
        match self {
            Edge::Off => "",
            Edge::On => " edge-aware",
            Edge::Pure => " edge-aware pure",
        }
    }
}

/// One filter setting of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct Choice {
    /// `none` or the kernel's name.
    pub filter: String,
    pub kernel: Option<Method>,
    pub target: Target,
    pub edge_aware: Edge,
    /// An unfiltered render with adaptive sampling at this threshold (its spp is the most a
    /// pixel takes), instead of uniform sampling.
    pub adaptive: Option<f32>,
}

impl Choice {
    /// The unfiltered render.
    pub fn none() -> Self {
        Choice {
            filter: "none".into(),
            kernel: None,
            target: Target::None,
            edge_aware: Edge::Off,
            adaptive: None,
        }
    }

    /// The unfiltered render with adaptive sampling; `results.csv` names it `adaptive:T`.
    pub fn adaptive(threshold: f32) -> Self {
        Choice { filter: format!("adaptive:{threshold}"), adaptive: Some(threshold), ..Choice::none() }
    }

    /// Whether this is the uniform unfiltered render, the base every other setting is read
    /// against.
    pub fn is_base(&self) -> bool {
        self.kernel.is_none() && self.adaptive.is_none()
    }

    /// A short label: `weighted3 indirect edge-aware`.
    pub fn label(&self) -> String {
        if let Some(t) = self.adaptive {
            return format!("adaptive {t}");
        }
        match self.kernel {
            None => "unfiltered".into(),
            Some(_) => {
                format!("{} {}{}", self.filter, self.target.name(), self.edge_aware.label())
            }
        }
    }

    /// The setting as `results.csv` records it (as [`Row::key`] reads it back).
    pub fn key(&self) -> (String, String, Edge) {
        (self.filter.clone(), self.target.name().to_string(), self.edge_aware)
    }
}

/// Every combination of the filters, targets and edge modes asked for; `none` once, unfiltered.
pub fn choices(filters: &[String], targets: &[Target], edge: &[Edge]) -> Result<Vec<Choice>, ConvergeError> {
    let mut out = Vec::new();
    for f in filters {
        if f == "none" {
            out.push(Choice::none());
            continue;
        }
        let kernel = Method::parse(f).map_err(ConvergeError::Input)?;
        for &target in targets {
            if target == Target::None {
                return Err(ConvergeError::Input(
                    "--targets takes indirect, image and components (the unfiltered run is the filter `none`)".into(),
                ));
            }
            for &edge_aware in edge {
                out.push(Choice {
                    filter: kernel.name(),
                    kernel: Some(kernel.clone()),
                    target,
                    edge_aware,
                    adaptive: None,
                });
            }
        }
    }
    if !out.contains(&Choice::none()) {
        // The equal-quality column reads the unfiltered curve: it is always measured.
        out.insert(0, Choice::none());
    }
    Ok(out)
}

/// A `converge` run.
#[derive(Clone, Debug)]
pub struct Plan {
    pub scene_path: PathBuf,
    /// Width, height, depth and the base seed come from here; `spp` and `seed` vary.
    pub options: RenderOptions,
    pub spps: Vec<u32>,
    pub seeds: u32,
    /// The samplers to measure, each with every setting (the options' own is not used),
    /// independent first: the base of the comparison.
    pub samplers: Vec<SamplerKind>,
    pub choices: Vec<Choice>,
    /// A reference image, or `None` to render (and cache) one at `reference_spp`.
    pub reference: Option<PathBuf>,
    pub reference_spp: u32,
    /// The sample count whose difference images (Figure 6) are written.
    pub diff_spp: Option<u32>,
    /// Also render with adaptive sampling at this threshold, up to each spp.
    pub adaptive: Option<f32>,
    pub out: PathBuf,
}

/// One row of `results.csv`.
#[derive(Clone, Debug, PartialEq)]
pub struct Row {
    pub scene: String,
    pub accel: String,
    pub sampler: SamplerKind,
    pub spp: u32,
    pub seed: u32,
    pub filter: String,
    pub target: String,
    pub edge_aware: Edge,
    pub render_seconds: f64,
    pub filter_seconds: f64,
    pub sse: f64,
    pub rmse: f64,
    pub relmse: f64,
    /// The RMSE over the pixels on object borders (of the render's object IDs).
    pub rmse_border: f64,
    /// The run's key ([`Plan::run_key`]): a hash of the scene's files and of every setting that
    /// changes a number. Empty for a row written before there was one (never used again).
    pub run: String,
}

pub const HEADER: &str = "scene,accel,sampler,spp,seed,filter,target,edge_aware,render_seconds,filter_seconds,sse,rmse,relmse,rmse_border,run";

impl Row {
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{},{},{},{},{},{:.6},{:.6},{:.9e},{:.9e},{:.9e},{:.9e},{}",
            self.scene.replace(',', ";"),
            self.accel,
            self.sampler,
            self.spp,
            self.seed,
            self.filter.replace(',', " "),
            self.target,
            self.edge_aware.csv(),
            self.render_seconds,
            self.filter_seconds,
            self.sse,
            self.rmse,
            self.relmse,
            self.rmse_border,
            self.run
        )
    }

    /// A row from a line of `results.csv`; `None` for a line a stopped run left half written.
    /// A line without the sampler column (written before there was a choice) was rendered
    /// with independent sampling; one without the run column has no key.
    pub fn parse(line: &str) -> Option<Row> {
        let mut f: Vec<&str> = line.trim_end().split(',').collect();
        let run = match f.len() {
            15 => f.pop()?.to_string(),
            13 | 14 => String::new(),
            _ => return None,
        };
        let sampler = match f.len() {
            14 => SamplerKind::parse(f.remove(2))?,
            13 => SamplerKind::Independent,
            _ => return None,
        };
        if !run.chars().all(|c| c.is_ascii_hexdigit()) {
            return None;
        }
        Some(Row {
            scene: f[0].to_string(),
            accel: f[1].to_string(),
            sampler,
            spp: f[2].parse().ok()?,
            seed: f[3].parse().ok()?,
            filter: f[4].to_string(),
            target: f[5].to_string(),
            edge_aware: Edge::parse(f[6])?,
            render_seconds: f[7].parse().ok()?,
            filter_seconds: f[8].parse().ok()?,
            sse: f[9].parse().ok()?,
            rmse: f[10].parse().ok()?,
            relmse: f[11].parse().ok()?,
            rmse_border: f[12].parse().ok()?,
            run,
        })
    }

    /// Whether every number of the row is finite.
    pub fn is_finite(&self) -> bool {
        [self.render_seconds, self.filter_seconds, self.sse, self.rmse, self.relmse, self.rmse_border]
            .iter()
            .all(|v| v.is_finite())
    }

    /// The setting this row measured.
    pub fn key(&self) -> (String, String, Edge) {
        (self.filter.clone(), self.target.clone(), self.edge_aware)
    }
}

/// What identifies a row of a run: its sampler, spp, seed index and setting.
type RowId = (SamplerKind, u32, u32, (String, String, Edge));

/// What a run reports as it goes.
pub enum Event<'a> {
    /// Samples (pixels x spp) done, for a progress bar over the whole run.
    Samples(u64),
    /// A line for the user.
    Message(&'a str),
}

#[derive(Debug, thiserror::Error)]
pub enum ConvergeError {
    #[error("{0}")]
    Input(String),
    #[error("{0}")]
    Failed(String),
}

impl Plan {
    /// The samples the run takes, the reference's included when it must be rendered (what
    /// an earlier run left done is counted as it is skipped).
    pub fn total_samples(&self, scene: &Scene) -> u64 {
        let pixels = self.options.width as u64 * self.options.height as u64;
        let reference = match (&self.reference, self.run_key(scene)) {
            (None, Ok(key)) if !self.reference_cache(&key).exists() => self.reference_spp as u64,
            _ => 0,
        };
        let renders = (1 + self.adaptive.is_some() as u64) * self.samplers.len() as u64;
        pixels * (self.spps.iter().map(|&s| s as u64).sum::<u64>() * self.seeds as u64 * renders + reference)
    }

    fn scene_name(&self) -> String {
        self.scene_path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
    }

    /// The seed of test render `k` (the reference uses another).
    fn seed(&self, k: u32) -> u64 {
        self.options.seed.wrapping_add(1 + k as u64)
    }

    /// The sampler of a rendered reference: sobol when the run measures it (the least error for
    /// the samples), else the one the run measures (`samplers` lists independent first).
    pub fn reference_sampler(&self) -> SamplerKind {
        self.samplers.last().copied().unwrap_or_default()
    }

    /// The run's key: a hash of the scene file, every file it reads (meshes, their material
    /// libraries, image textures), and every setting that changes a number: the image size,
    /// the path length, the base seed, the reference (the given file's contents, or the spp and
    /// sampler it is rendered with) and the program's version. The rows' own spp, seed,
    /// sampler and setting are columns of their own. A row of another key is not used.
    pub fn run_key(&self, scene: &Scene) -> Result<String, ConvergeError> {
        let mut key = RunKey::of_scene(scene).map_err(ConvergeError::Input)?;
        let o = &self.options;
        key.numbers(&[o.width as u64, o.height as u64, o.max_depth as u64, o.seed]);
        match &self.reference {
            Some(path) => {
                key.bytes(b"reference file");
                key.file(path).map_err(ConvergeError::Input)?;
            }
            None => {
                key.bytes(b"reference rendered");
                key.numbers(&[self.reference_spp as u64]);
                key.bytes(self.reference_sampler().name().as_bytes());
            }
        }
        Ok(key.finish())
    }

    /// The cache file of the rendered reference, named by the run's key.
    pub fn reference_cache(&self, key: &str) -> PathBuf {
        self.out.join(format!("reference-{}spp-{key}.exr", self.reference_spp))
    }
}

/// Reads the rows of `results.csv`. A line that is not a row (half written by a stopped run,
/// or damaged: a byte that is not UTF-8 spoils only its own line) is skipped.
pub fn read_rows(path: &Path) -> Vec<Row> {
    let bytes = fs::read(path).unwrap_or_default();
    bytes
        .split(|&b| b == b'\n')
        .skip(1)
        .filter_map(|l| std::str::from_utf8(l).ok())
        .filter_map(Row::parse)
        .collect()
}

/// The reference image: the given file, or a render at `reference_spp` cached in the output
/// directory.
fn reference(
    plan: &Plan,
    scene: &Scene,
    key: &str,
    report: &(dyn Fn(Event) + Sync),
) -> Result<Image, ConvergeError> {
    // A NaN or an infinity in the reference makes every error NaN: refused at once, as
    // `compare` refuses it.
    let finite = |img: Image, path: &Path| {
        let bad = img.pixels.iter().filter(|p| !p.is_finite()).count();
        if bad > 0 {
            return Err(ConvergeError::Input(format!(
                "the reference {}: {bad} of its {} pixels are NaN or infinite: no error can be measured",
                path.display(),
                img.pixels.len()
            )));
        }
        Ok(img)
    };
    if let Some(path) = &plan.reference {
        let img = finite(film::read_image(path).map_err(|e| ConvergeError::Input(e.0))?, path)?;
        if (img.width, img.height) != (plan.options.width, plan.options.height) {
            return Err(ConvergeError::Input(format!(
                "the reference {} is {}x{}, the renders {}x{}",
                path.display(),
                img.width,
                img.height,
                plan.options.width,
                plan.options.height
            )));
        }
        return Ok(img);
    }
    let cache = plan.reference_cache(key);
    if let Ok(img) = film::read_image(&cache) {
        report(Event::Message(&format!("reference: {} (cached)", cache.display())));
        return finite(img, &cache);
    }
    report(Event::Message(&format!("reference: rendering {} spp", plan.reference_spp)));
    let mut options = plan.options.clone();
    options.spp = plan.reference_spp;
    options.seed = plan.options.seed.wrapping_add(0x5eed_0000_0000);
    options.sampler = plan.reference_sampler();
    options.adaptive = None;
    let out = render::render(scene, &options, &|n| report(Event::Samples(n)))
        .map_err(|e| ConvergeError::Failed(e.to_string()))?;
    let image = out.film.raw.clone();
    let meta = render::metadata(scene, &options, out.stats.seconds);
    film::write_film(out.film, image.clone(), None, &cache, 0.0, &meta)
        .map_err(|e| ConvergeError::Failed(e.to_string()))?;
    Ok(image)
}

/// What a run measured: the rows of this scene, backend and key, earlier and new.
pub struct Measured {
    pub rows: Vec<Row>,
    /// Rows of this scene and backend in `results.csv` measured under another key (other
    /// scene contents or settings, or from before there was a key): kept in the file, not used.
    pub unused: usize,
}

/// Brings an existing `results.csv` of an older layout to [`HEADER`]'s: its rows rewritten
/// (those without a key keep an empty one), lines that are not rows kept as they are.
fn upgrade_csv(path: &Path) -> Result<(), ConvergeError> {
    let failed = |e: std::io::Error| ConvergeError::Failed(format!("{}: {e}", path.display()));
    let bytes = match fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(failed(e)),
    };
    let mut lines = bytes.split(|&b| b == b'\n');
    if lines.next().is_some_and(|h| h == HEADER.as_bytes()) {
        return Ok(());
    }
    let mut text = format!("{HEADER}\n").into_bytes();
    for line in lines.filter(|l| !l.is_empty()) {
        match std::str::from_utf8(line).ok().and_then(Row::parse) {
            Some(row) => text.extend_from_slice(row.csv().as_bytes()),
            None => text.extend_from_slice(line),
        }
        text.push(b'\n');
    }
    film::write_text(path, &text).map_err(|e| ConvergeError::Failed(e.to_string()))
}

/// Runs the plan: renders what `results.csv` lacks, appends its rows, and returns every row of
/// this scene, backend and key (earlier and new).
pub fn run(plan: &Plan, scene: &Scene, report: &(dyn Fn(Event) + Sync)) -> Result<Measured, ConvergeError> {
    let key = plan.run_key(scene)?;
    let created = !plan.out.exists();
    fs::create_dir_all(&plan.out)
        .map_err(|e| ConvergeError::Input(format!("cannot create {}: {e}", plan.out.display())))?;
    let reference = reference(plan, scene, &key, report).inspect_err(|_| {
        // A bad reference leaves no empty directory behind (`remove_dir` takes only an empty one).
        if created {
            let _ = fs::remove_dir(&plan.out);
        }
    })?;
    let csv_path = plan.out.join("results.csv");
    upgrade_csv(&csv_path)?;
    let (scene_name, accel) = (plan.scene_name(), plan.options.accel.name().to_string());
    let (mut rows, others): (Vec<Row>, Vec<Row>) = read_rows(&csv_path)
        .into_iter()
        .filter(|r| r.scene == scene_name && r.accel == accel)
        .partition(|r| r.run == key);
    // A row with a number that is not finite (an edited file; no run writes one) would hang the
    // plots' log axes: it is left out, and measured again.
    let before = rows.len();
    rows.retain(Row::is_finite);
    if rows.len() < before {
        report(Event::Message(&format!(
            "note: {}: {} row(s) of this run with a number that is not finite (inf or NaN) left out, \
             and measured again",
            csv_path.display(),
            before - rows.len()
        )));
    }
    let unused = others.len();
    if unused > 0 {
        report(Event::Message(&format!(
            "{}: {unused} row(s) of {scene_name} on {accel} were measured with other scene files or \
             settings (size, path length, seed, reference): kept in the file, not used",
            csv_path.display()
        )));
    }
    let done: HashSet<RowId> = rows.iter().map(|r| (r.sampler, r.spp, r.seed, r.key())).collect();
    let fresh = !csv_path.exists();
    let mut csv = fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&csv_path)
        .map_err(|e| ConvergeError::Failed(format!("{}: {e}", csv_path.display())))?;
    let write_line = |csv: &mut fs::File, line: &str| {
        // One write of a whole line: a stop can only lose the line being written.
        csv.write_all(format!("{line}\n").as_bytes())
            .and_then(|()| csv.flush())
            .map_err(|e| ConvergeError::Failed(format!("{}: {e}", csv_path.display())))
    };
    if fresh {
        write_line(&mut csv, HEADER)?;
    } else if fs::read(&csv_path).is_ok_and(|b| b.last().is_some_and(|&c| c != b'\n')) {
        // A stopped run left half a line: end it, so it stays one malformed (skipped) line.
        write_line(&mut csv, "")?;
    }
    let pixels = plan.options.width as u64 * plan.options.height as u64;
    // The uniform render, filtered every way; then the adaptive one, unfiltered.
    let adaptive = plan.adaptive.map(Choice::adaptive);
    let renders: Vec<Vec<&Choice>> = [plan.choices.iter().collect(), adaptive.iter().collect()]
        .into_iter()
        .filter(|c: &Vec<&Choice>| !c.is_empty())
        .collect();
    // Sample count by sample count, so a run stopped half way has every sampler at low spp.
    let runs: Vec<(SamplerKind, u32, &Vec<&Choice>)> = plan
        .samplers
        .iter()
        .flat_map(|&s| {
            let renders = &renders;
            (0..plan.seeds).flat_map(move |k| renders.iter().map(move |c| (s, k, c)))
        })
        .collect();
    let mut scales = std::collections::HashMap::new();
    for &spp in &plan.spps {
        for &(sampler, k, choices) in &runs {
            let todo: Vec<&Choice> =
                choices.iter().copied().filter(|c| !done.contains(&(sampler, spp, k, c.key()))).collect();
            if todo.is_empty() {
                report(Event::Samples(pixels * spp as u64));
                continue;
            }
            let mut options = plan.options.clone();
            options.spp = spp;
            options.seed = plan.seed(k);
            options.sampler = sampler;
            options.adaptive = choices[0].adaptive;
            let out = render::render(scene, &options, &|n| report(Event::Samples(n)))
                .map_err(|e| ConvergeError::Failed(e.to_string()))?;
            let borders = metrics::object_borders(&out.film.object, out.film.width, out.film.height);
            // Every difference image at this spp at the scale of the first sampler's unfiltered
            // render, so they compare across settings and samplers.
            let diff_scale =
                *scales.entry(spp).or_insert_with(|| metrics::difference_scale(&out.film.raw, &reference));
            for choice in todo {
                let start = Instant::now();
                let (image, _) = composite(&out.film, choice.kernel.as_ref(), choice.target, &stops(choice));
                let filter_seconds =
                    if choice.kernel.is_some() { start.elapsed().as_secs_f64() } else { 0.0 };
                let e = metrics::compare(&image, &reference).map_err(|e| ConvergeError::Failed(e.0))?;
                if k == 0 && plan.diff_spp == Some(spp) {
                    let name = choice.label().replace(' ', "-");
                    let prefix = if plan.samplers.len() > 1 { format!("{sampler}-") } else { String::new() };
                    let path = plan.out.join(format!("diff-{spp}spp-{prefix}{name}.png"));
                    film::write(
                        &metrics::difference_image_scaled(&image, &reference, diff_scale),
                        &path,
                        0.0,
                    )
                    .map_err(|e| ConvergeError::Failed(e.to_string()))?;
                }
                let row = Row {
                    scene: scene_name.clone(),
                    accel: accel.clone(),
                    sampler,
                    spp,
                    seed: k,
                    filter: choice.filter.clone(),
                    target: choice.target.name().to_string(),
                    edge_aware: choice.edge_aware,
                    render_seconds: out.stats.seconds,
                    filter_seconds,
                    sse: e.sse,
                    rmse: e.rmse,
                    relmse: e.relmse,
                    rmse_border: metrics::rmse_masked(&image, &reference, &borders),
                    run: key.clone(),
                };
                write_line(&mut csv, &row.csv())?;
                rows.push(row);
            }
        }
    }
    Ok(Measured { rows, unused })
}

fn stops(c: &Choice) -> EdgeStops {
    EdgeStops { object: c.edge_aware != Edge::Off, pure: c.edge_aware == Edge::Pure, ..Default::default() }
}

/// Writes `summary.md` and the two plots for what was measured.
pub fn report(plan: &Plan, measured: &Measured) -> Result<String, ConvergeError> {
    let rows = &measured.rows;
    let mut choices = plan.choices.clone();
    choices.extend(plan.adaptive.map(Choice::adaptive));
    let several = plan.samplers.len() > 1;
    let tables: Vec<(SamplerKind, summary::Table)> = plan
        .samplers
        .iter()
        .map(|&k| {
            let mine: Vec<Row> = rows.iter().filter(|r| r.sampler == k).cloned().collect();
            let table = summary::Table::new(&mine, &choices, &plan.spps);
            (k, if several { table.labelled(k) } else { table })
        })
        .collect();
    let mut md = String::new();
    let _ = writeln!(md, "# converge: {}\n", plan.scene_name());
    let samplers: Vec<&str> = plan.samplers.iter().map(|s| s.name()).collect();
    let _ = writeln!(
        md,
        "{}x{}, {} seed(s) a point, accelerator {}, sampler {}, reference {}.\n",
        plan.options.width,
        plan.options.height,
        plan.seeds,
        plan.options.accel.name(),
        samplers.join(" and "),
        match &plan.reference {
            Some(p) => p.display().to_string(),
            None => format!("rendered at {} spp ({})", plan.reference_spp, plan.reference_sampler()),
        }
    );
    if measured.unused > 0 {
        let _ = writeln!(
            md,
            "results.csv holds {} more row(s) of this scene and accelerator, measured with other scene \
             files or settings: they are not used here.\n",
            measured.unused
        );
    }
    if several {
        md.push_str("## The samplers compared\n\n");
        md.push_str(&summary::samplers_markdown(&tables));
    }
    for (kind, table) in &tables {
        if several {
            let _ = writeln!(md, "\n## Sampler {kind}\n");
        }
        md.push_str(&table.markdown());
        md.push_str(if several {
            "\n### The paper's claims, checked\n\n"
        } else {
            "\n## The paper's claims, checked\n\n"
        });
        md.push_str(&claims::check(table));
    }
    film::write_text(&plan.out.join("summary.md"), &md).map_err(|e| ConvergeError::Failed(e.to_string()))?;
    let all = summary::Table { series: tables.into_iter().flat_map(|(_, t)| t.series).collect() };
    plot::error_plot(&all, false, &plan.out.join("error-vs-spp.png")).map_err(ConvergeError::Failed)?;
    plot::error_plot(&all, true, &plan.out.join("error-vs-time.png")).map_err(ConvergeError::Failed)?;
    Ok(md)
}
