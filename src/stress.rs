//! `lightsplit stress`: numerical stability as a table. Each row builds an adversarial scene,
//! renders or probes it on one backend, and reports a measured figure and whether it passed.
//! The tests run every row on both backends.
//!
//! The main probe is the self-hit count: from the point each pixel sees, rays leave the surface
//! (towards the sun, cosine-distributed, and grazing at 0.06 to 6 degrees) from the robust
//! origin every secondary ray uses. Every shape of the probed scenes is convex, so a ray that
//! leaves one can never meet it again: any hit of the shape it started on is a self-hit, the
//! cause of shadow acne, and is counted exactly.

use std::collections::BTreeSet;
use std::path::Path;

use glam::{Vec2, Vec3, Vec3A};

use crate::accel::{self, Accel, Backend};
use crate::component::Component;
use crate::film::{self, Film};
use crate::math::{cosine_hemisphere, luminance, Frame};
use crate::render::camera::PinholeCamera;
use crate::render::sampler::Sampler;
use crate::render::surface::surface;
use crate::render::{render, RenderOptions, RenderOutput};
use crate::scene::{self, Geometry, Mesh, Scene, Shape};

/// One measured row of the table.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Row {
    /// The row's name, as [`names`] lists it.
    pub name: String,
    /// What was measured, with its numbers.
    pub figure: String,
    /// Whether the figure is within the row's bound: a row outside it fails, whatever it is.
    pub pass: bool,
    /// What the row checks, and its bound.
    pub note: String,
}

/// An error that stops the suite: a scene that does not parse or a backend that cannot build
/// (both bugs of the suite or the machine, not stability results).
#[derive(Debug, thiserror::Error)]
pub enum StressError {
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error(transparent)]
    Render(#[from] crate::render::RenderError),
    #[error(transparent)]
    Accel(#[from] accel::AccelError),
    #[error("{0}")]
    Io(String),
}

/// One row of the suite: its name and how it is measured.
type RowFn = fn(&Ctx) -> Result<Row, StressError>;

/// The suite's rows in table order, each named once beside what it runs, so no row can be
/// listed without being run or run without being listed.
const ROWS: &[(&str, RowFn)] = &[
    ("translate 1e3", |c| c.moved(1e3, 1.0)),
    ("translate 1e5", |c| c.moved(1e5, 1.0)),
    ("translate 1e6", |c| c.moved(1e6, 1.0)),
    ("translate 1e7", |c| c.moved(1e7, 1.0)),
    ("translate 1e8", |c| c.moved(1e8, 1.0)),
    ("scale 1e-4", |c| c.moved(0.0, 1e-4)),
    ("scale 1e-2", |c| c.moved(0.0, 1e-2)),
    ("scale 1e2", |c| c.moved(0.0, 1e2)),
    ("scale 1e5", |c| c.moved(0.0, 1e5)),
    ("grazing rays, 2e4-unit plane", Ctx::grazing),
    ("degenerate triangles", Ctx::degenerate),
    ("zero-radius sphere", Ctx::zero_radius),
    ("zero-power lights", Ctx::zero_power),
    ("only zero-power lights", Ctx::only_zero_power),
    ("sun of 0.01 degrees", Ctx::tiny_sun),
    ("radiance 1e-6 to 1e6", Ctx::radiance_range),
    ("overflowing light", Ctx::overflow),
    ("watertight: subdivided plane", Ctx::watertight_plane),
    ("watertight: closed sphere, inside", Ctx::watertight_sphere),
];

/// The suite's row names, in table order.
pub fn names() -> impl Iterator<Item = &'static str> {
    ROWS.iter().map(|(name, _)| *name)
}

/// Image size and samples of the rendered rows: small, so the suite takes seconds.
const SIZE: u32 = 48;
const SPP: u32 = 16;

/// Runs the row named `name` (one of [`names`]) on `backend`.
pub fn run_row(name: &str, backend: Backend, threads: Option<usize>) -> Result<Row, StressError> {
    let (name, run) = ROWS
        .iter()
        .find(|(n, _)| *n == name)
        .ok_or_else(|| StressError::Io(format!("no stress row named `{name}`")))?;
    let row = run(&Ctx { backend, threads })?;
    Ok(Row { name: name.to_string(), ..row })
}

/// The backend and threads every row uses.
struct Ctx {
    backend: Backend,
    threads: Option<usize>,
}

/// A row before it is named.
fn row(figure: String, pass: bool, note: impl Into<String>) -> Row {
    Row { name: String::new(), figure, pass, note: note.into() }
}

/// The distance between adjacent f32 values at magnitude `x`.
fn spacing(x: f64) -> f64 {
    let x = x.abs() as f32;
    (f32::from_bits(x.to_bits() + 1) - x) as f64
}

fn parse(text: &str) -> Result<Scene, StressError> {
    Ok(scene::file::parse(Path::new("stress.toml"), text)?)
}

/// The probed scene: a floor, an analytic sphere on it, a box and a tilted quad, under a low
/// sun and a uniform sky, moved to `offset` (on every axis) and scaled by `scale` about the
/// origin before the offset. Coordinates are written in f64 so each is rounded to f32 once, as
/// a scene file of the moved scene would be.
fn moved_scene(offset: f64, scale: f64) -> String {
    let p = |x: f64, y: f64, z: f64| {
        format!("[{:e}, {:e}, {:e}]", offset + scale * x, offset + scale * y, offset + scale * z)
    };
    format!(
        "[camera]\nposition = {}\nlook_at = {}\nup = [0, 1, 0]\nfov = 40\n\
         [film]\nwidth = {SIZE}\nheight = {SIZE}\nspp = {SPP}\n[render]\nmax_depth = 3\nseed = 1\n\
         [[material]]\nname = \"white\"\ntype = \"diffuse\"\ncolor = [0.7, 0.7, 0.7]\n\
         [[material]]\nname = \"red\"\ntype = \"diffuse\"\ncolor = [0.7, 0.1, 0.1]\n\
         [[shape]]\ntype = \"quad\"\nname = \"floor\"\nmaterial = \"white\"\nvertices = [{}, {}, {}, {}]\n\
         [[shape]]\ntype = \"sphere\"\nname = \"ball\"\nmaterial = \"red\"\ncenter = {}\nradius = {:e}\n\
         [[shape]]\ntype = \"box\"\nname = \"box\"\nmaterial = \"white\"\nmin = {}\nmax = {}\n\
         [[shape]]\ntype = \"quad\"\nname = \"ramp\"\nmaterial = \"red\"\nvertices = [{}, {}, {}, {}]\n\
         [[light]]\ntype = \"sun\"\ndirection = [0.5, 0.45, -0.6]\nirradiance = [3, 3, 3]\n\
         [[light]]\ntype = \"sky\"\nradiance = [0.3, 0.3, 0.3]\n",
        p(0.3, 1.6, -4.2),
        p(0.0, 0.5, 0.0),
        p(-3.0, 0.0, -3.0),
        p(-3.0, 0.0, 3.0),
        p(3.0, 0.0, 3.0),
        p(3.0, 0.0, -3.0),
        p(-0.8, 0.6, 0.0),
        scale * 0.6,
        p(0.3, 0.0, -0.2),
        p(1.1, 0.9, 0.6),
        p(-1.2, 1.2, 2.0),
        p(1.4, 1.2, 2.0),
        p(1.4, 0.0, 1.0),
        p(-1.2, 0.0, 1.0),
    )
}

/// Self-hits of rays leaving the point each pixel's centre sees, on a scene of convex shapes.
/// Returns (rays, self-hits).
fn self_hits<A: Accel>(scene: &Scene, accel: &A, toward: Vec3) -> (u64, u64) {
    let camera = PinholeCamera::new(&scene.camera, scene.film.width, scene.film.height);
    let (mut rays, mut hits) = (0, 0);
    for y in 0..scene.film.height {
        for x in 0..scene.film.width {
            let ray = camera.ray(x, y, Vec2::splat(0.5));
            let Some(hit) = accel.intersect(&ray) else { continue };
            let s = surface(scene, &ray, &hit);
            let side = if s.ng.dot(ray.dir) < 0.0 { s.ng } else { -s.ng };
            let frame = Frame::new(side);
            let origin = s.origin(side);
            let mut sampler = Sampler::new(7, (y * scene.film.width + x) as u64, 0);
            let mut dirs = vec![toward];
            dirs.extend((0..8).map(|_| frame.to_world(cosine_hemisphere(sampler.next_2d()))));
            // Grazing: elevations of 1e-3, 1e-2 and 1e-1 radians at random azimuths.
            for e in [1e-3f32, 1e-2, 1e-1] {
                let phi = std::f32::consts::TAU * sampler.next_1d();
                dirs.push(frame.to_world(Vec3::new(phi.cos(), phi.sin(), e).normalize()));
            }
            for d in dirs.into_iter().filter(|d| d.dot(side) > 0.0) {
                rays += 1;
                if accel.intersect(&accel::Ray::new(origin, d)).is_some_and(|h| h.shape == hit.shape) {
                    hits += 1;
                }
            }
        }
    }
    (rays, hits)
}

impl Ctx {
    fn options(&self, scene: &Scene) -> RenderOptions {
        let mut options = RenderOptions::from_scene(scene);
        options.accel = self.backend;
        options.threads = self.threads;
        options
    }

    fn render(&self, scene: &Scene) -> Result<RenderOutput, StressError> {
        Ok(render(scene, &self.options(scene), &|_| {})?)
    }

    /// Self-hits on `scene` with this backend (see [`self_hits`]).
    fn probe(&self, scene: &Scene, toward: Vec3) -> Result<(u64, u64), StressError> {
        struct Probe<'s> {
            scene: &'s Scene,
            toward: Vec3,
        }
        impl accel::UseAccel for Probe<'_> {
            type Output = (u64, u64);
            fn with<A: Accel>(self, accel: &A) -> (u64, u64) {
                self_hits(self.scene, accel, self.toward)
            }
        }
        let hints = accel::BuildHints::default();
        Ok(self.backend.build(scene, self.threads, hints, Probe { scene, toward })?)
    }

    /// Translation and scale: the same image (mean over the objects within 1%), no self-hits,
    /// and no pixel of the sun's direct light darker than at the origin.
    fn moved(&self, offset: f64, scale: f64) -> Result<Row, StressError> {
        let reference = parse(&moved_scene(0.0, 1.0))?;
        let scene = parse(&moved_scene(offset, scale))?;
        let base = self.render(&reference)?.film;
        let film = self.render(&scene)?.film;
        let toward = Vec3::new(0.5, 0.45, -0.6).normalize();
        let (rays, hits) = self.probe(&scene, toward)?;

        let on_objects = |f: &Film| -> f64 {
            let pixels = f.raw.pixels.iter().zip(&base.object);
            pixels.filter(|(_, &o)| o >= 0.0).map(|(p, _)| luminance(*p) as f64).sum()
        };
        let ratio = on_objects(&film) / on_objects(&base);
        // Darker by more than a quarter of the samples could explain at an edge that moved.
        let direct = |f: &Film, i: usize| luminance(f.components[Component::Direct].pixels[i]);
        let darker = (0..base.object.len())
            .filter(|&i| film.object[i] == base.object[i] && direct(&film, i) < 0.75 * direct(&base, i))
            .count();
        let size = 6.0 * scale;
        // The scene is stored relative to its camera: f32's step is that of the farthest point
        // from the camera (about the scene's size away), not of the offset, which f64 holds.
        let step = spacing(2.0 * size);
        let bound = film.object.len() / 100;
        let figure = format!(
            "mean {ratio:.4}x the origin's, self-hits {hits}/{rays}, pixels 25% darker {darker} (bound {bound}); f32 step around the camera {step:.1e} = {:.1e} of the scene, f64 step at the offset {:.1e}",
            step / size,
            offset.abs() * f64::EPSILON
        );
        let pass = (ratio - 1.0).abs() < 0.01 && hits == 0 && darker <= bound;
        let note = "the beauty's mean over the objects within 1% of the scene at the origin, not one \
             self-hit, and at most 1% of the pixels 25% darker than at the origin (shadow and \
             silhouette edges that moved). The scene is read in f64 and stored relative to its \
             camera before it is rounded to f32, so a far offset costs nothing";
        Ok(row(figure, pass, note))
    }

    /// A camera 5 cm above a plane 2e4 units wide looks towards its horizon under a sun 2 degrees
    /// high: every pixel below the horizon hits the plane, every lit pixel's direct light is the
    /// analytic E rho cos / pi, and no ray leaving the plane meets it.
    fn grazing(&self) -> Result<Row, StressError> {
        let elevation = 2.0f32.to_radians();
        let toward = Vec3::new(0.0, elevation.sin(), elevation.cos());
        let text = format!(
            "[camera]\nposition = [0, 0.05, 0]\nlook_at = [0, 0.03, 1]\nup = [0, 1, 0]\nfov = 30\n\
             [film]\nwidth = {SIZE}\nheight = {SIZE}\nspp = 4\n[render]\nmax_depth = 1\n\
             [[material]]\nname = \"white\"\ntype = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n\
             [[shape]]\ntype = \"quad\"\nname = \"plane\"\nmaterial = \"white\"\n\
             vertices = [[-1e4, 0, -1e4], [-1e4, 0, 1e4], [1e4, 0, 1e4], [1e4, 0, -1e4]]\n\
             [[light]]\ntype = \"sun\"\ndirection = [{}, {}, {}]\nirradiance = [1, 1, 1]\nangular_diameter = 0.01\n",
            toward.x, toward.y, toward.z
        );
        let scene = parse(&text)?;
        let film = self.render(&scene)?.film;
        let (rays, hits) = self.probe(&scene, toward)?;
        // Rows entirely below the horizon (the camera looks 1.1 degrees down, fov 30).
        let camera = PinholeCamera::new(&scene.camera, SIZE, SIZE);
        let below = |y: u32| camera.ray(0, y, Vec2::ZERO).dir.y < -1e-5;
        let (mut holes, mut worst, mut lit) = (0, 0.0f64, 0);
        let expected = 0.5 * elevation.sin() as f64 / std::f64::consts::PI;
        for y in (0..SIZE).filter(|&y| below(y)) {
            for x in 0..SIZE {
                let i = (y * SIZE + x) as usize;
                if film.object[i] < 0.0 || film.coverage[i] < 1.0 {
                    holes += 1;
                    continue;
                }
                lit += 1;
                let d = film.components[Component::Direct].pixels[i].x as f64;
                worst = worst.max((d / expected - 1.0).abs());
            }
        }
        // A sample direction within the sun's disc changes cos by up to its angular radius
        // times tan of the angle to the normal.
        let bound = sun_bound(0.01, 88.0);
        let figure = format!(
            "holes {holes}/{}, self-hits {hits}/{rays}, direct light off E rho cos / pi by {worst:.1e} (bound {bound:.1e})",
            lit + holes
        );
        Ok(row(
            figure,
            holes == 0 && hits == 0 && worst <= bound,
            "every pixel below the horizon hits the plane, its direct light within the bound the sun's disc allows, no self-hit",
        ))
    }

    /// Zero-area triangles (a repeated vertex, three collinear points, all three equal), also in
    /// an emissive mesh, change nothing: the image equals the one without them, and no sample is
    /// lost.
    fn degenerate(&self) -> Result<Row, StressError> {
        let base = parse(&moved_scene(0.0, 1.0))?;
        let mut with = base.clone();
        // In the scene's stored (camera-relative) coordinates, so that zero-area triangles are
        // built exactly as they are traced.
        let at = |p: Vec3| stored(&base, p);
        let light = at(Vec3::new(0.0, 2.5, 0.0));
        let mut panel = vec![
            [
                light + Vec3::new(-0.3, 0.0, -0.3),
                light + Vec3::new(0.3, 0.0, -0.3),
                light + Vec3::new(0.3, 0.0, 0.3),
            ],
            [
                light + Vec3::new(-0.3, 0.0, -0.3),
                light + Vec3::new(0.3, 0.0, 0.3),
                light + Vec3::new(-0.3, 0.0, 0.3),
            ],
        ];
        let mut without = base.clone();
        add_mesh(&mut without, "panel", &panel, Vec3::splat(5.0));
        // Dyadic coordinates: `a + 2 (b - a)` is exact, so the second triangle is exactly
        // collinear (near the world's (0.1, 0.9, -1) and (0.8, 0.4, -0.5)).
        let a = Vec3::new(-0.25, -0.75, 3.25);
        let b = Vec3::new(0.5, -1.25, 3.75);
        let degenerate = [[a, a, b], [a, b, a + 2.0 * (b - a)], [b, b, b], [light, light, light + Vec3::X]];
        panel.extend(degenerate);
        add_mesh(&mut with, "panel", &panel, Vec3::splat(5.0));
        add_mesh(&mut with, "dust", &degenerate, Vec3::ZERO);
        self.identical(
            &without,
            &with,
            "zero-area triangles are never hit and never sampled as lights: the image is identical",
        )
    }

    /// A sphere of radius 0, plain and emissive, changes nothing.
    fn zero_radius(&self) -> Result<Row, StressError> {
        let text = moved_scene(0.0, 1.0);
        let with = format!(
            "{text}[[shape]]\ntype = \"sphere\"\nname = \"dot\"\ncenter = [0.2, 0.5, -1]\nradius = 0\n\
             [[shape]]\ntype = \"sphere\"\nname = \"star\"\ncenter = [0, 2, 0]\nradius = 0\nemission = [100, 100, 100]\n"
        );
        self.identical(
            &parse(&text)?,
            &parse(&with)?,
            "a point-sized sphere is invisible and, emissive, sheds no light: the image is identical",
        )
    }

    /// Lights of zero power next to a real one change nothing.
    fn zero_power(&self) -> Result<Row, StressError> {
        let text = moved_scene(0.0, 1.0);
        let with = format!("{text}{ZERO_LIGHTS}");
        self.identical(
            &parse(&text)?,
            &parse(&with)?,
            "a point, spot, sun and sky of zero power beside the scene's lights: the image is identical",
        )
    }

    /// Passes when `with` renders exactly the image `without` does, with no sample lost.
    fn identical(&self, without: &Scene, with: &Scene, note: &str) -> Result<Row, StressError> {
        let (one, two) = (self.render(without)?, self.render(with)?);
        let diff = max_difference(&one.film, &two.film);
        let nonfinite = two.stats.nonfinite_samples;
        let figure =
            format!("image max abs. difference {diff:.1e} from the scene without them, non-finite samples {nonfinite}");
        Ok(row(figure, diff == 0.0 && nonfinite == 0, note))
    }

    /// A scene lit only by zero-power lights is black, with no NaN.
    fn only_zero_power(&self) -> Result<Row, StressError> {
        let text = moved_scene(0.0, 1.0);
        let dark = text.split("[[light]]").next().unwrap_or(&text).to_string();
        let out = self.render(&parse(&format!("{dark}{ZERO_LIGHTS}"))?)?;
        let max = out.film.raw.pixels.iter().map(|p| p.max_element()).fold(0.0f32, f32::max);
        let finite = out.film.raw.pixels.iter().all(|p| p.is_finite());
        let nonfinite = out.stats.nonfinite_samples;
        Ok(row(
            format!("brightest pixel {max:.1e}, non-finite samples {nonfinite}"),
            max == 0.0 && finite && nonfinite == 0,
            "no light to pick: every pixel exactly black",
        ))
    }

    /// A sun of 0.01 degrees (solid angle 2.4e-8 sr, 1 - cos = 3.8e-9, below f32's epsilon at 1)
    /// lights a plane as exactly as a point direction would: E rho cos / pi.
    fn tiny_sun(&self) -> Result<Row, StressError> {
        let mut pass = true;
        let mut figures = Vec::new();
        let dir = Vec3::new(0.3, 1.0, 0.2).normalize();
        let tilt = (dir.y as f64).acos().to_degrees();
        for diameter in [0.01, 0.53] {
            let text = format!(
                "[camera]\nposition = [0, 3, -3]\nlook_at = [0, 0, 0]\nfov = 30\n\
                 [film]\nwidth = {SIZE}\nheight = {SIZE}\nspp = 4\n[render]\nmax_depth = 1\n\
                 [[material]]\nname = \"grey\"\ntype = \"diffuse\"\ncolor = [0.5, 0.5, 0.5]\n\
                 [[shape]]\ntype = \"quad\"\nmaterial = \"grey\"\nvertices = [[-9, 0, -9], [-9, 0, 9], [9, 0, 9], [9, 0, -9]]\n\
                 [[light]]\ntype = \"sun\"\ndirection = [{}, {}, {}]\nirradiance = [2, 2, 2]\nangular_diameter = {diameter}\n",
                dir.x, dir.y, dir.z
            );
            let film = self.render(&parse(&text)?)?.film;
            let expected = 2.0 * 0.5 * dir.y as f64 / std::f64::consts::PI;
            let off = film.components[Component::Direct]
                .pixels
                .iter()
                .map(|p| (p.x as f64 / expected - 1.0).abs())
                .fold(0.0, f64::max);
            let bound = sun_bound(diameter, tilt);
            pass &= off <= bound;
            figures.push(format!("{diameter} deg: worst pixel off by {off:.1e} (bound {bound:.1e})"));
        }
        Ok(row(
            figures.join(", "),
            pass,
            "direct light on a plane within the bound the sun's disc allows of E rho cos / pi in every pixel; the cone is sampled from 1 - cos, exact for tiny suns",
        ))
    }

    /// Thirteen emitters of radiance 1e-6 to 1e6 in one image: each pixel on one reads back its
    /// radiance from the render (to f32 rounding), from an EXR (exactly) and from a Radiance HDR
    /// (to RGBE's 8-bit mantissa).
    fn radiance_range(&self) -> Result<Row, StressError> {
        let mut text = String::from(
            "[camera]\nposition = [0, 0, -10]\nlook_at = [0, 0, 0]\nfov = 9.2\n\
             [film]\nwidth = 104\nheight = 8\nspp = 4\n[render]\nmax_depth = 1\n\
             [[material]]\nname = \"black\"\ntype = \"diffuse\"\ncolor = [0, 0, 0]\n",
        );
        // Panels side by side, each wider than a pixel column's footprint.
        let (w, half) = (1.55f32, 0.7f32);
        for k in -6..=6 {
            let x = k as f32 * w;
            text.push_str(&format!(
                "[[shape]]\ntype = \"quad\"\nmaterial = \"black\"\nemission = [1e{k}, 1e{k}, 1e{k}]\n\
                 vertices = [[{}, -1, 0], [{}, 1, 0], [{}, 1, 0], [{}, -1, 0]]\n",
                x - half,
                x - half,
                x + half,
                x + half
            ));
        }
        let scene = parse(&text)?;
        let film = self.render(&scene)?.film;
        let dir = tempfile_dir()?;
        let (exr, hdr) = (dir.join("range.exr"), dir.join("range.hdr"));
        let io = |e: film::WriteError| StressError::Io(e.to_string());
        film::write(&film.raw, &exr, 0.0).map_err(io)?;
        film::write(&film.raw, &hdr, 0.0).map_err(io)?;
        let back_exr = film::read_image(&exr).map_err(|e| StressError::Io(e.0))?;
        let back_hdr = film::read_image(&hdr).map_err(|e| StressError::Io(e.0))?;
        let _ = std::fs::remove_dir_all(&dir);

        let (mut seen, mut render_err, mut exr_err, mut hdr_err) = (0, 0.0f64, 0.0f64, 0.0f64);
        for (i, p) in film.raw.pixels.iter().enumerate() {
            // A pixel whose every sample saw one panel.
            if film.coverage[i] < 1.0 || film.object[i] < 0.0 {
                continue;
            }
            let expected = 10f64.powi(film.object[i] as i32 - 6);
            seen += 1;
            let rel = |v: f32| (v as f64 / expected - 1.0).abs();
            render_err = render_err.max(rel(p.x));
            // The files against the film they were written from.
            exr_err = exr_err.max((back_exr.pixels[i].x as f64 / p.x as f64 - 1.0).abs());
            hdr_err = hdr_err.max((back_hdr.pixels[i].x as f64 / p.x as f64 - 1.0).abs());
        }
        let decades =
            film.object.iter().filter(|&&o| o >= 0.0).map(|&o| o as i32).collect::<BTreeSet<_>>().len();
        let figure = format!(
            "{decades} decades in {seen} pixels: render off by {render_err:.1e}, EXR {exr_err:.1e}, HDR {hdr_err:.1e}"
        );
        Ok(row(
            figure,
            decades == 13 && render_err < 1e-6 && exr_err == 0.0 && hdr_err < 1.0 / 128.0,
            "render to f32 rounding (1e-6), EXR exact, Radiance HDR within its 8-bit mantissa (1/128)",
        ))
    }

    /// A point light of 3e38 W/sr half a unit above a plane overflows f32: those samples are
    /// dropped and counted, and the film stays finite.
    fn overflow(&self) -> Result<Row, StressError> {
        let text = format!(
            "[camera]\nposition = [0, 2, -3]\nlook_at = [0, 0, 0]\n[film]\nwidth = {SIZE}\nheight = {SIZE}\nspp = 4\n\
             [[shape]]\ntype = \"quad\"\nvertices = [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]]\n\
             [[light]]\ntype = \"point\"\nposition = [0, 0.5, 0]\nintensity = [3e38, 3e38, 3e38]\n"
        );
        let out = self.render(&parse(&text)?)?;
        let film = &out.film;
        let finite = std::iter::once(&film.raw)
            .chain(&film.components)
            .all(|layer| layer.pixels.iter().all(|p| p.is_finite()));
        let (n, total) = (out.stats.nonfinite_samples, out.stats.samples);
        Ok(row(
            format!("{n} of {total} samples non-finite, dropped and counted; film finite: {finite}"),
            finite && n > 0 && n < total,
            "an irradiance beyond f32's range: the sample is dropped (a zero), never written",
        ))
    }

    /// A 300 x 300 grid of quads (180,000 triangles sharing every edge) seen from above: every
    /// sample of every pixel hits it.
    fn watertight_plane(&self) -> Result<Row, StressError> {
        let n = 300;
        let mut scene = watertight_scene("position = [0.3, 4, -1.1]\nlook_at = [0.01, 0, 0.02]\nfov = 50\n")?;
        let mut tris = Vec::with_capacity(2 * n * n);
        let at = |i: usize, j: usize| {
            Vec3::new(-3.0 + 6.0 * i as f32 / n as f32, 0.0, -3.0 + 6.0 * j as f32 / n as f32)
        };
        for i in 0..n {
            for j in 0..n {
                let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
                tris.push([a, d, c]);
                tris.push([a, c, b]);
            }
        }
        let tris: Vec<[Vec3; 3]> = tris.iter().map(|t| t.map(|p| stored(&scene, p))).collect();
        add_mesh(&mut scene, "grid", &tris, Vec3::ZERO);
        self.holes(
            &scene,
            "every sample of every pixel hits the grid; a ray between two triangles would miss",
        )
    }

    /// A closed UV sphere of 3,968 triangles seen from inside: no ray escapes.
    fn watertight_sphere(&self) -> Result<Row, StressError> {
        let mut scene =
            watertight_scene("position = [0.1, 0.05, -0.2]\nlook_at = [0.3, 0.2, 1]\nfov = 100\n")?;
        let ball: Vec<[Vec3; 3]> = uv_sphere(32).iter().map(|t| t.map(|p| stored(&scene, p))).collect();
        add_mesh(&mut scene, "ball", &ball, Vec3::ZERO);
        self.holes(
            &scene,
            "from inside a closed mesh every sample hits it, at shared edges and at the poles' fans",
        )
    }

    /// Counts the pixels where some sample saw no object: sample 0 hit nothing, or another
    /// sample saw something else (coverage below 1; the scene has one object).
    fn holes(&self, scene: &Scene, note: &str) -> Result<Row, StressError> {
        let film = self.render(scene)?.film;
        let holes = film.object.iter().zip(&film.coverage).filter(|(&o, &c)| o < 0.0 || c < 1.0).count();
        let samples = film.object.len() as u32 * SPP;
        Ok(row(
            format!("pixels with a hole {holes} of {} ({samples} samples)", film.object.len()),
            holes == 0,
            note,
        ))
    }
}

/// A 64 x 64 scene with these `[camera]` lines under a white sky, for the watertight rows.
fn watertight_scene(camera: &str) -> Result<Scene, StressError> {
    parse(&format!(
        "[camera]\n{camera}[film]\nwidth = 64\nheight = 64\nspp = {SPP}\n[render]\nmax_depth = 1\n\
         [[light]]\ntype = \"sky\"\nradiance = [1, 1, 1]\n"
    ))
}

/// A point, a spot, a sun and a sky, all of zero power.
const ZERO_LIGHTS: &str = "[[light]]\ntype = \"point\"\nposition = [0, 3, 0]\nintensity = [0, 0, 0]\n\
    [[light]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -1, 0]\nintensity = [0, 0, 0]\ncone_angle = 30\n\
    [[light]]\ntype = \"sun\"\ndirection = [0, 1, 0]\nirradiance = [0, 0, 0]\n\
    [[light]]\ntype = \"sky\"\nradiance = [0, 0, 0]\n";

/// The largest relative change of E rho cos / pi over the directions of a sun of `diameter`
/// degrees whose centre is `tilt` degrees from the normal, plus f32 rounding: cos(tilt + r)
/// differs from cos(tilt) by about r tan(tilt).
fn sun_bound(diameter: f64, tilt: f64) -> f64 {
    let r = (0.5 * diameter).to_radians();
    r * tilt.to_radians().tan() + 1e-5
}

/// The largest per-channel difference between two renders' beauty.
fn max_difference(a: &Film, b: &Film) -> f32 {
    a.raw.pixels.iter().zip(&b.raw.pixels).map(|(p, q)| (*p - *q).abs().max_element()).fold(0.0, f32::max)
}

/// A point of the world as `scene` stores it: relative to its origin (the camera), rounded once.
fn stored(scene: &Scene, p: Vec3) -> Vec3 {
    (p.as_dvec3() - scene.origin).as_vec3()
}

/// Adds a triangle soup (in the scene's stored coordinates: see [`stored`]) as one shape (its
/// own object) with the default material.
fn add_mesh(scene: &mut Scene, name: &str, triangles: &[[Vec3; 3]], emission: Vec3) {
    let positions: Vec<Vec3A> = triangles.iter().flatten().map(|&p| p.into()).collect();
    let indices: Vec<[u32; 3]> = (0..triangles.len() as u32).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
    let material = scene.materials.len() as u32;
    scene.materials.push(scene::Material::Diffuse { albedo: Vec3::splat(0.8) });
    scene.objects.push(name.to_string());
    scene.shapes.push(Shape {
        name: name.to_string(),
        geometry: Geometry::Triangles(Mesh::new(positions.into(), indices.into(), None, None)),
        material,
        emission,
        object: scene.objects.len() as u32 - 1,
    });
}

/// A closed unit sphere of `n` rings and `2n` segments, wound outwards: triangle fans at the
/// poles, quads split in two between; neighbours share their vertices bit for bit.
fn uv_sphere(n: usize) -> Vec<[Vec3; 3]> {
    let vertex = |i: usize, j: usize| {
        if i == 0 {
            return Vec3::Y;
        }
        if i == n {
            return -Vec3::Y;
        }
        let theta = std::f64::consts::PI * i as f64 / n as f64;
        let phi = std::f64::consts::TAU * (j % (2 * n)) as f64 / (2 * n) as f64;
        Vec3::new((theta.sin() * phi.cos()) as f32, theta.cos() as f32, (theta.sin() * phi.sin()) as f32)
    };
    let mut tris = Vec::new();
    for i in 0..n {
        for j in 0..2 * n {
            let (a, b, c, d) = (vertex(i, j), vertex(i, j + 1), vertex(i + 1, j + 1), vertex(i + 1, j));
            if i != 0 {
                tris.push([a, b, c]);
            }
            if i != n - 1 {
                tris.push([a, c, d]);
            }
        }
    }
    tris
}

/// A fresh directory for one row's files: unique in this process too, since rows may run on
/// several threads at once (the tests run both backends side by side).
fn tempfile_dir() -> Result<std::path::PathBuf, StressError> {
    static NEXT: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("lightsplit-stress-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).map_err(|e| StressError::Io(format!("{}: {e}", dir.display())))?;
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_names_are_unique_and_unknown_names_are_errors() {
        let unique: BTreeSet<&str> = names().collect();
        assert_eq!(unique.len(), ROWS.len());
        assert!(matches!(run_row("no such row", Backend::Bvh, Some(1)), Err(StressError::Io(_))));
    }
}
