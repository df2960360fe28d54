//! `lightsplit._native`: the library's render, filter, compare and merge for Python. The
//! Python package around it (`python/lightsplit/__init__.py`) gives the documented API; this
//! module holds what needs Rust. A render runs through the same [`Job`] as `lightsplit render`
//! (the same options over the scene file's, the same features, the same film), without the
//! GIL, and its layers become NumPy arrays of the values the command line's EXR holds.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use glam::Vec3;
use lightsplit::accel::Backend;
use lightsplit::error::Classify;
use lightsplit::film::layers::LAYERS;
use lightsplit::film::{self, Film, Format, Image, Metadata, Sums};
use lightsplit::filter::{composite, Overrides, Pixels, Setting};
use lightsplit::job::{Job, Request};
use lightsplit::output::{self, Layer};
use lightsplit::part;
use lightsplit::render::RenderStats;
use lightsplit::scene::{self, Aov, LoadOptions, SamplerKind, Scene as SceneData};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};

/// An error of the library as Python's: bad input a `ValueError`, a failure on good input a
/// `RuntimeError`, each with the command line's message.
fn py_error(e: impl Classify) -> PyErr {
    if e.is_input() {
        PyValueError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

/// A filter target by its command-line name (`--filter-target`).
fn target_of(name: Option<&str>) -> PyResult<Option<lightsplit::filter::Target>> {
    name.map(|n| {
        lightsplit::filter::Target::from_name(n)
            .ok_or_else(|| PyValueError::new_err(format!("filter target `{n}` is not a target")))
    })
    .transpose()
}

/// A loaded scene and the settings a render takes from it, which Python may change first.
#[pyclass(module = "lightsplit._native")]
struct Scene {
    scene: Arc<SceneData>,
    filter: Setting,
    width: Option<u32>,
    height: Option<u32>,
    spp: Option<u32>,
    seed: Option<u64>,
    max_depth: Option<u32>,
}

/// Reads a scene file of any format the command line reads; `camera` picks a glTF file's
/// camera, `defines` sets a Mitsuba file's parameters.
#[pyfunction]
#[pyo3(signature = (path, camera=None, defines=None))]
fn load(path: PathBuf, camera: Option<String>, defines: Option<Vec<(String, String)>>) -> PyResult<Scene> {
    let options = LoadOptions { camera, defines: defines.unwrap_or_default() };
    let scene = scene::load_with(&path, &options).map_err(py_error)?;
    let filter = Setting::of_scene(&scene).map_err(py_error)?;
    Ok(Scene {
        scene: Arc::new(scene),
        filter,
        width: None,
        height: None,
        spp: None,
        seed: None,
        max_depth: None,
    })
}

fn vec3(v: Vec3) -> [f32; 3] {
    v.to_array()
}

#[pymethods]
impl Scene {
    /// The scene file.
    #[getter]
    fn path(&self) -> PathBuf {
        self.scene.path.clone()
    }

    #[getter]
    fn width(&self) -> u32 {
        self.width.unwrap_or(self.scene.film.width)
    }

    #[setter]
    fn set_width(&mut self, value: u32) {
        self.width = Some(value);
    }

    #[getter]
    fn height(&self) -> u32 {
        self.height.unwrap_or(self.scene.film.height)
    }

    #[setter]
    fn set_height(&mut self, value: u32) {
        self.height = Some(value);
    }

    #[getter]
    fn spp(&self) -> u32 {
        self.spp.unwrap_or(self.scene.film.spp)
    }

    #[setter]
    fn set_spp(&mut self, value: u32) {
        self.spp = Some(value);
    }

    #[getter]
    fn seed(&self) -> u64 {
        self.seed.unwrap_or(self.scene.render.seed)
    }

    #[setter]
    fn set_seed(&mut self, value: u64) {
        self.seed = Some(value);
    }

    #[getter]
    fn max_depth(&self) -> u32 {
        self.max_depth.unwrap_or(self.scene.render.max_depth)
    }

    #[setter]
    fn set_max_depth(&mut self, value: u32) {
        self.max_depth = Some(value);
    }

    /// The camera: position, look_at, up (world space), fov (vertical, degrees), and, when
    /// the camera has them, orthographic (the view's height) and lens (radius, focus distance).
    #[getter]
    fn camera<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let c = &self.scene.camera;
        let d = PyDict::new(py);
        d.set_item("position", vec3(c.position))?;
        d.set_item("look_at", vec3(c.look_at))?;
        d.set_item("up", vec3(c.up))?;
        d.set_item("fov", c.fov)?;
        d.set_item("orthographic", c.orthographic)?;
        d.set_item("lens", c.lens.as_ref().map(|l| (l.radius, l.focus_distance)))?;
        Ok(d)
    }

    /// Moves the camera: each argument given replaces the camera's value.
    #[pyo3(signature = (position=None, look_at=None, up=None, fov=None))]
    fn set_camera(
        &mut self,
        position: Option<[f32; 3]>,
        look_at: Option<[f32; 3]>,
        up: Option<[f32; 3]>,
        fov: Option<f32>,
    ) -> PyResult<()> {
        let mut camera = self.scene.camera;
        if let Some(p) = position {
            camera.position = Vec3::from(p);
        }
        if let Some(p) = look_at {
            camera.look_at = Vec3::from(p);
        }
        if let Some(p) = up {
            camera.up = Vec3::from(p);
        }
        if let Some(f) = fov {
            camera.fov = f;
        }
        let forward = camera.look_at - camera.position;
        let finite = [camera.position, camera.look_at, camera.up].iter().all(|v| v.is_finite());
        if !finite || forward.length_squared() == 0.0 || forward.cross(camera.up).length_squared() == 0.0 {
            return Err(PyValueError::new_err(
                "camera: position, look_at and up must be finite, look_at away from position, and up not along the view",
            ));
        }
        if !(camera.fov > 0.0 && camera.fov < 180.0) {
            return Err(PyValueError::new_err(format!(
                "camera: fov {} is not in (0, 180) degrees",
                camera.fov
            )));
        }
        // A render under way holds the scene only while it runs (the GIL is back when it ends), so
        // this clones the scene at most when Python keeps another reference to it.
        Arc::make_mut(&mut self.scene).camera = camera;
        Ok(())
    }

    /// The names of the objects, in object-ID order (the `objectid` layer's values).
    #[getter]
    fn objects(&self) -> Vec<String> {
        self.scene.objects.clone()
    }

    /// Each material's kind and parameters, as the library shows it.
    #[getter]
    fn materials(&self) -> Vec<String> {
        self.scene.materials.iter().map(|m| format!("{m:?}")).collect()
    }

    /// The named materials: (index into `materials`, name).
    #[getter]
    fn material_names(&self) -> Vec<(u32, String)> {
        self.scene.material_names.clone()
    }

    /// Each light's kind and parameters, as the library shows it.
    #[getter]
    fn lights(&self) -> Vec<String> {
        self.scene.lights.iter().map(|l| format!("{l:?}")).collect()
    }

    /// Notes the loader left (what it approximated or skipped).
    #[getter]
    fn notes(&self) -> Vec<String> {
        self.scene.notes.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "Scene({:?}: {}x{}, {} spp, seed {}, {} objects, {} materials, {} lights)",
            self.scene.path.display().to_string(),
            self.width(),
            self.height(),
            self.spp(),
            self.seed(),
            self.scene.objects.len(),
            self.scene.materials.len(),
            self.scene.lights.len()
        )
    }

    /// Renders; see the Python wrapper's `Scene.render` for the arguments. Returns the render
    /// and whether a KeyboardInterrupt stopped it (its samples kept).
    #[pyo3(signature = (spp=None, seed=None, threads=None, accel="embree", sampler=None, denoise=false, filter=None, filter_target=None, part=None, aovs=None, light_groups=false, cryptomatte=false, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn render(
        &self,
        py: Python<'_>,
        spp: Option<u32>,
        seed: Option<u64>,
        threads: Option<usize>,
        accel: &str,
        sampler: Option<&str>,
        denoise: bool,
        filter: Option<String>,
        filter_target: Option<String>,
        part: Option<String>,
        aovs: Option<Vec<String>>,
        light_groups: bool,
        cryptomatte: bool,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<(Render, bool)> {
        let accel = match accel {
            "embree" => Backend::Embree,
            "bvh" => Backend::Bvh,
            other => return Err(PyValueError::new_err(format!("accel `{other}`: embree or bvh"))),
        };
        let sampler = match sampler {
            None => None,
            Some(name) => {
                Some(SamplerKind::ALL.into_iter().find(|k| k.name() == name).ok_or_else(|| {
                    PyValueError::new_err(format!("sampler `{name}`: independent or sobol"))
                })?)
            }
        };
        if threads == Some(0) {
            return Err(PyValueError::new_err("threads must be at least 1"));
        }
        let target = target_of(filter_target.as_deref())?;
        let aovs = aovs
            .unwrap_or_default()
            .iter()
            .map(|a| Aov::parse(a).map_err(PyValueError::new_err))
            .collect::<PyResult<Vec<_>>>()?;
        let request = Request {
            // An EXR: every layer is computed, as the command line's EXR has them.
            output: PathBuf::from("render.exr"),
            width: self.width,
            height: self.height,
            spp: spp.or(self.spp),
            seed: seed.or(self.seed),
            max_depth: self.max_depth,
            sampler,
            accel,
            threads,
            filter: Overrides { method: filter, denoise, target, ..Overrides::default() },
            part,
            aovs,
            light_groups,
            cryptomatte,
            ..Request::default()
        };
        let scene = &*self.scene;
        let mut job = Job::new(scene, &self.filter, request, |_| None).map_err(py_error)?;
        let total = job.total_samples();
        let stop = AtomicBool::new(false);
        let done = AtomicU64::new(0);
        let finished = AtomicBool::new(false);
        let mut interrupted = false;
        let mut callback_error = None;
        let rendered = std::thread::scope(|s| {
            let worker = s.spawn(|| {
                let r = job.render(
                    &|n| {
                        done.fetch_add(n, Ordering::Relaxed);
                    },
                    &stop,
                );
                finished.store(true, Ordering::Release);
                r
            });
            // This thread waits without the GIL, and with it every tenth of a second looks for
            // a signal (Ctrl-C: the render stops after its pass) and reports progress.
            loop {
                py.detach(|| {
                    for _ in 0..20 {
                        if finished.load(Ordering::Acquire) {
                            break;
                        }
                        std::thread::sleep(Duration::from_millis(5));
                    }
                });
                // Ctrl-C (KeyboardInterrupt, from the signal check or raised in the callback)
                // stops the render and keeps its samples; another error from the callback
                // stops it and is raised.
                let mut stopped_by = |e: PyErr| {
                    if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
                        interrupted = true;
                    } else {
                        callback_error.get_or_insert(e);
                    }
                    stop.store(true, Ordering::Relaxed);
                };
                if let Err(e) = py.check_signals() {
                    stopped_by(e);
                }
                if let (Some(cb), false) = (&progress, stop.load(Ordering::Relaxed)) {
                    if let Err(e) = cb.call1(py, (done.load(Ordering::Relaxed), total)) {
                        stopped_by(e);
                    }
                }
                if finished.load(Ordering::Acquire) {
                    break;
                }
            }
            worker.join()
        });
        let rendered = match rendered {
            Ok(r) => r.map_err(py_error)?,
            Err(_) => return Err(PyRuntimeError::new_err("the render panicked")),
        };
        if let Some(e) = callback_error {
            return Err(e);
        }
        let mut out = rendered.into_output();
        // A part keeps its sums and its file's header, for a merge or a part file.
        let part = match (job.is_part(), out.sums.take()) {
            (true, Some(sums)) => {
                Some(Box::new((job.part_header(&out.stats).map_err(py_error)?, Arc::new(sums))))
            }
            _ => None,
        };
        let meta = Metadata {
            filter: job.filter_label(),
            ..lightsplit::render::metadata(scene, &job.options, out.stats.seconds)
        };
        let threads = job
            .options
            .threads
            .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()));
        let mut render = py.detach(|| Render::new(out.film, job.setting.clone(), meta, out.stats, threads));
        render.part = part;
        Ok((render, interrupted))
    }
}

/// A finished render: the film, the final image (filtered when a filter was on), the filtered
/// indirect layer, the metadata a file records, and the counts.
#[pyclass(module = "lightsplit._native", frozen)]
struct Render {
    film: Film,
    final_image: Image,
    filtered: Option<Pixels>,
    setting: Setting,
    meta: Metadata,
    stats: RenderStats,
    filter_seconds: f64,
    threads: usize,
    /// A part of a render (`part=`): its part file's header and its sums.
    part: Option<Box<(part::Header, Arc<Sums>)>>,
}

impl Render {
    /// The render of `film` under `setting`: filtered as `lightsplit render` filters before
    /// writing.
    fn new(film: Film, setting: Setting, meta: Metadata, stats: RenderStats, threads: usize) -> Render {
        let start = std::time::Instant::now();
        // On a pool thread: a Python thread is none, and each of the filter's parallel steps
        // started from outside the pool is a hand-over (0.90x the filter's seconds at 256x256
        // in the pool; docs/RESULTS.md, "The filter's images from its pool").
        let (final_image, filtered) = lightsplit::accel::in_pool(|| {
            composite(&film, setting.method.as_ref(), setting.target, &setting.stops)
        });
        let final_image = final_image.into_owned();
        let filter_seconds = if setting.method.is_some() { start.elapsed().as_secs_f64() } else { 0.0 };
        Render { film, final_image, filtered, setting, meta, stats, filter_seconds, threads, part: None }
    }
}

/// `values` (pixel after pixel, `channels` each) as a float32 array of `height` x `width` x
/// `channels`, taking the vector (no copy).
fn array<'py>(
    py: Python<'py>,
    values: Vec<f32>,
    height: u32,
    width: u32,
    channels: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let flat = PyArray1::from_vec(py, values);
    Ok(flat.reshape([height as usize, width as usize, channels])?.into_any())
}

/// An EXR channel's layer and channel names: `objectid.ID` is (`objectid`, `ID`); a channel
/// without a layer (`A`) is both.
fn split_channel(full: &str) -> (&str, &str) {
    full.split_once('.').unwrap_or((full, full))
}

fn image_values(image: &Image) -> Vec<f32> {
    image.pixels.iter().flat_map(|p| p.to_array()).collect()
}

#[pymethods]
impl Render {
    #[getter]
    fn width(&self) -> u32 {
        self.film.width
    }

    #[getter]
    fn height(&self) -> u32 {
        self.film.height
    }

    /// The final image (the EXR's R, G, B): height x width x 3, float32.
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        array(py, image_values(&self.final_image), self.film.height, self.film.width, 3)
    }

    /// Every other layer of the EXR the command line writes, by its name before the dot
    /// (`raw`, `direct`, `albedo`, `normal`, `depth`, `objectid` with its ID and coverage,
    /// `A`, the variance layers, the halves, `indirect_filtered`, the AOVs), each height x
    /// width x channels, and the channels' names.
    fn layers<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyDict>, Bound<'py, PyDict>)> {
        let (w, h) = (self.film.width, self.film.height);
        let arrays = PyDict::new(py);
        let names = PyDict::new(py);
        // Layers that share a prefix (objectid.ID, objectid.coverage) become one array.
        let mut grouped: Vec<(String, Vec<String>, Vec<Vec<f32>>)> = Vec::new();
        let mut add =
            |name: &str, channel: &str, values: Vec<f32>| match grouped.iter_mut().find(|g| g.0 == name) {
                Some(g) => {
                    g.1.push(channel.to_string());
                    g.2.push(values);
                }
                None => grouped.push((name.to_string(), vec![channel.to_string()], vec![values])),
            };
        if let Some(f) = &self.filtered {
            for (c, channel) in ["R", "G", "B"].iter().enumerate() {
                add("indirect_filtered", channel, f.iter().map(|p| p[c]).collect());
            }
        }
        for (layer, values) in self.film.layers() {
            let width = layer.width();
            let name = split_channel(layer.channels[0]).0;
            // A layer alone under its name (all but objectid's two): its interleaved values
            // are the array's, copied once.
            if LAYERS.iter().filter(|l| split_channel(l.channels[0]).0 == name).count() == 1 {
                let channels: Vec<&str> = layer.channels.iter().map(|full| split_channel(full).1).collect();
                arrays.set_item(name, array(py, values.to_vec(), h, w, width)?)?;
                names.set_item(name, PyList::new(py, channels)?)?;
                continue;
            }
            for (c, full) in layer.channels.iter().enumerate() {
                let (name, channel) = split_channel(full);
                add(name, channel, values.iter().skip(c).step_by(width).copied().collect());
            }
        }
        for aov in &self.film.aovs {
            for (c, channel) in ["R", "G", "B"].iter().enumerate() {
                add(&aov.name, channel, aov.image.pixels.iter().map(|p| p[c]).collect());
            }
        }
        // Cryptomatte's rank layers (CryptoObject00: R, G, B, A, ...), as the EXR has them.
        for matte in &self.film.mattes {
            for (full, values) in matte.rank_channels() {
                let (name, channel) = split_channel(&full);
                add(name, channel, values);
            }
        }
        for (name, channels, planes) in grouped {
            let n = w as usize * h as usize;
            let k = planes.len();
            let mut values = vec![0.0f32; n * k];
            for (c, plane) in planes.iter().enumerate() {
                for (i, v) in plane.iter().enumerate() {
                    values[i * k + c] = *v;
                }
            }
            arrays.set_item(&name, array(py, values, h, w, k)?)?;
            names.set_item(&name, PyList::new(py, channels)?)?;
        }
        Ok((arrays, names))
    }

    /// The counts: seconds, build_seconds, filter_seconds, samples, rays, samples_per_second,
    /// rays_per_second, nonfinite_samples, min_spp, max_spp, interrupted, threads.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let s = &self.stats;
        let d = PyDict::new(py);
        let per_second = |n: u64| n as f64 / s.seconds.max(1e-9);
        d.set_item("seconds", s.seconds)?;
        d.set_item("build_seconds", s.build_seconds)?;
        d.set_item("filter_seconds", self.filter_seconds)?;
        d.set_item("samples", s.samples)?;
        d.set_item("rays", s.rays)?;
        d.set_item("samples_per_second", per_second(s.samples))?;
        d.set_item("rays_per_second", per_second(s.rays))?;
        d.set_item("nonfinite_samples", s.nonfinite_samples)?;
        d.set_item("min_spp", s.min_spp)?;
        d.set_item("max_spp", s.max_spp)?;
        d.set_item("interrupted", s.interrupted)?;
        d.set_item("threads", self.threads)?;
        Ok(d)
    }

    /// The header attributes of the render's Cryptomatte types (`cryptomatte/<key>/name`,
    /// `.../manifest`, ...), as the EXR holds them.
    #[getter]
    fn cryptomatte<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        for (key, value) in self.film.matte_attributes() {
            d.set_item(key, value)?;
        }
        Ok(d)
    }

    /// The filter the final image had: `atrous:... on components`, or None.
    #[getter]
    fn filter(&self) -> Option<String> {
        lightsplit::job::filter_label(&self.setting)
    }

    /// The part this render is (`I/N`), or None.
    #[getter]
    fn part(&self) -> Option<String> {
        self.part.as_ref().map(|p| p.0.part.to_string())
    }

    /// Writes the render as `lightsplit render` would: an EXR with every layer (compressed as
    /// `compression` says, as `--exr-compression`), or the final image as PNG (with `exposure`
    /// stops) or HDR; a part as its part file (an EXR).
    #[pyo3(signature = (path, exposure=0.0, compression=None))]
    fn save(&self, py: Python<'_>, path: PathBuf, exposure: f32, compression: Option<&str>) -> PyResult<()> {
        let format = film::check_output(&path).map_err(py_error)?;
        if let Some(warning) = output::exposure_warning(exposure, format) {
            return Err(PyValueError::new_err(warning));
        }
        let compression =
            compression.map(film::ExrCompression::parse).transpose().map_err(PyValueError::new_err)?;
        if compression.is_some() && (format != Format::Exr || self.part.is_some()) {
            return Err(PyValueError::new_err(format!(
                "{}: compression applies to an .exr only, and not to a part file",
                path.display()
            )));
        }
        let meta = Metadata { compression: compression.unwrap_or_default(), ..self.meta.clone() };
        if let Some(held) = &self.part {
            if format != Format::Exr {
                return Err(PyValueError::new_err(format!(
                    "{}: a part is saved as its part file, an .exr, for a merge",
                    path.display()
                )));
            }
            return py.detach(|| part::write(&path, &held.1, &held.0).map_err(py_error));
        }
        // Filtered again on a pool thread, as [`Render::new`] filters.
        let written = py.detach(|| {
            lightsplit::accel::in_pool(|| {
                output::write(self.film.clone(), &self.setting, &path, Layer::Final, exposure, &meta)
            })
        });
        written.map(|_| ()).map_err(py_error)
    }

    /// This render filtered again with `filter` (a method as `--filter` takes it) on
    /// `target`, or with `--denoise`'s setting.
    #[pyo3(signature = (filter=None, target=None, denoise=false))]
    fn refilter(
        &self,
        py: Python<'_>,
        filter: Option<String>,
        target: Option<String>,
        denoise: bool,
    ) -> PyResult<Render> {
        let target = target_of(target.as_deref())?;
        let overrides = Overrides { method: filter, denoise, target, ..Overrides::default() };
        let setting = overrides.over(&Setting::default()).map_err(PyValueError::new_err)?;
        output::check_aov_target(
            &setting,
            &self.film.aovs.iter().map(|a| a.name.as_str()).collect::<Vec<_>>(),
        )
        .map_err(py_error)?;
        if setting.method.is_some()
            && output::filter_reads(&setting).variance
            && self.film.variance.is_empty()
        {
            return Err(PyValueError::new_err(
                "this filter reads each pixel's variance, which the film lacks",
            ));
        }
        let meta = Metadata { filter: lightsplit::job::filter_label(&setting), ..self.meta.clone() };
        Ok(py.detach(|| Render::new(self.film.clone(), setting, meta, self.stats, self.threads)))
    }
}

/// A render of layers given as arrays (`Render.layers`' names and shapes: `raw`, the
/// components, the guides, the variances, the halves), read as the EXR reader reads a file's
/// channels; layers the film does not know are refused, and a film without `raw` is an error.
#[pyfunction]
fn from_layers(
    py: Python<'_>,
    layers: std::collections::HashMap<String, PyReadonlyArray3<'_, f32>>,
) -> PyResult<Render> {
    let mut size = None;
    let mut channels: film::Channels = Vec::new();
    let mut names: Vec<&String> = layers.keys().collect();
    names.sort();
    for name in names {
        let a = layers[name].as_array();
        let (h, w, c) = a.dim();
        if *size.get_or_insert((w, h)) != (w, h) {
            return Err(PyValueError::new_err(format!("layer `{name}` is {w}x{h}, unlike the others")));
        }
        let defs: Vec<&str> = LAYERS
            .iter()
            .flat_map(|l| l.channels.iter().copied())
            .filter(|full| split_channel(full).0 == name)
            .collect();
        if defs.is_empty() {
            return Err(PyValueError::new_err(format!("`{name}` is not a layer of the film")));
        }
        if defs.len() != c {
            return Err(PyValueError::new_err(format!(
                "layer `{name}` has {c} channels; the film's has {}",
                defs.len()
            )));
        }
        for (i, full) in defs.into_iter().enumerate() {
            channels
                .push((full.to_string(), a.index_axis(numpy::ndarray::Axis(2), i).iter().copied().collect()));
        }
    }
    let Some((w, h)) = size else { return Err(PyValueError::new_err("no layers")) };
    let (Ok(width), Ok(height)) = (u32::try_from(w), u32::try_from(h)) else {
        return Err(PyValueError::new_err("the layers are too large"));
    };
    py.detach(|| {
        let film = Film::from_channels(width, height, &channels).map_err(PyValueError::new_err)?;
        Ok(Render::new(film, Setting::default(), Metadata::default(), RenderStats::default(), 0))
    })
}

/// Reads an EXR `lightsplit render` wrote (or a part file's merge) as a render: its layers, and
/// the final image it holds.
#[pyfunction]
fn read(py: Python<'_>, path: PathBuf) -> PyResult<Render> {
    py.detach(|| {
        let film = film::read_film(&path).map_err(|e| PyValueError::new_err(e.to_string()))?;
        let meta = Metadata::of_exr(&path).unwrap_or_default();
        let mut render = Render::new(film, Setting::default(), meta, RenderStats::default(), 0);
        // The file's own final image, which a filter may have made.
        if let Ok(final_image) = film::read_image(&path) {
            render.final_image = final_image;
        }
        Ok(render)
    })
}

/// The errors of `test` against `reference`, each a height x width x 3 array of float32: the
/// command line's `compare` metrics.
#[pyfunction]
fn compare(
    test: PyReadonlyArray3<'_, f32>,
    reference: PyReadonlyArray3<'_, f32>,
) -> PyResult<Vec<(&'static str, f64)>> {
    let image = |a: &PyReadonlyArray3<'_, f32>| -> PyResult<Image> {
        let a = a.as_array();
        let (h, w, c) = a.dim();
        if c != 3 {
            return Err(PyValueError::new_err(format!(
                "an image is height x width x 3; this one has {c} channels"
            )));
        }
        let (width, height) = (u32::try_from(w), u32::try_from(h));
        let (Ok(width), Ok(height)) = (width, height) else {
            return Err(PyValueError::new_err("the image is too large"));
        };
        let pixels = a
            .outer_iter()
            .flat_map(|row| row.outer_iter().map(|p| Vec3::new(p[0], p[1], p[2])).collect::<Vec<_>>())
            .collect();
        Ok(Image { width, height, pixels })
    };
    let e = lightsplit::metrics::compare(&image(&test)?, &image(&reference)?)
        .map_err(|e| PyValueError::new_err(e.0))?;
    Ok(vec![
        ("sse", e.sse),
        ("rmse", e.rmse),
        ("relmse", e.relmse),
        ("rmse_trimmed", e.rmse_trimmed),
        ("relmse_trimmed", e.relmse_trimmed),
    ])
}

/// Merges parts into one render, as `lightsplit merge` does: part files (`render --part I/N`)
/// and renders of parts (`part=`), in any mix; with `allow_missing`, whichever parts there are.
#[pyfunction]
#[pyo3(signature = (parts, allow_missing=false))]
fn merge(py: Python<'_>, parts: Vec<Bound<'_, PyAny>>, allow_missing: bool) -> PyResult<Render> {
    let error = |e: part::MergeError| PyValueError::new_err(e.to_string());
    let mut named = Vec::with_capacity(parts.len());
    for p in &parts {
        if let Ok(render) = p.cast::<Render>() {
            let render = render.get();
            let Some(held) = &render.part else {
                return Err(PyValueError::new_err(
                    "a render merged must be a part (rendered with part=), or a part file",
                ));
            };
            let name = format!("the render of part {}", held.0.part);
            named.push(part::Named::held(&name, held.0.clone(), Arc::clone(&held.1)));
        } else {
            named.push(part::Named::read(&p.extract::<PathBuf>()?).map_err(error)?);
        }
    }
    py.detach(|| {
        part::check(&named, allow_missing).map_err(error)?;
        let sums = part::merge(&named, &|| ()).map_err(error)?;
        let first = &named[0].header;
        let meta = Metadata {
            spp: Some(first.spp),
            extra: film::aov_attributes(&first.meta).collect(),
            ..first.meta.clone()
        };
        // The samples the parts hold; the seconds and rays stay each part's own.
        let (min_spp, max_spp) = sums.spp_range();
        let stats = RenderStats {
            samples: sums.samples.iter().map(|&n| n as u64).sum(),
            min_spp,
            max_spp,
            ..RenderStats::default()
        };
        Ok(Render::new(sums.into_means(), Setting::default(), meta, stats, 0))
    })
}

#[pymodule(gil_used = false)]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(from_layers, m)?)?;
    m.add_class::<Scene>()?;
    m.add_class::<Render>()?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
