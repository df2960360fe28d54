//! The `lightsplit` command line: parse (the grammar is in `cli.rs`), call the library, print.
//! No rendering logic and no output rules here: those live in the library.

mod cli;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};

use clap::Parser;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use cli::{Cli, Command};
use lightsplit::error::Classify;
use lightsplit::film;
use lightsplit::filter::Setting;
use lightsplit::scene;

/// Bad input: a scene file, an argument or an output path that cannot work.
const EXIT_INPUT: u8 = 2;
/// A failure while working on valid input.
const EXIT_FAILURE: u8 = 1;

/// A failure with its exit status.
struct Failure {
    code: u8,
    message: String,
}

impl Failure {
    /// Nothing more to say: standard output's reader has gone (a closed pipe, as in `| head`).
    /// The work is done; the command ends quietly with status 0, as `rg` and `fd` do.
    fn reader_gone() -> Self {
        Failure { code: 0, message: String::new() }
    }
    fn input(message: impl ToString) -> Self {
        Failure { code: EXIT_INPUT, message: message.to_string() }
    }
    fn failed(message: impl ToString) -> Self {
        Failure { code: EXIT_FAILURE, message: message.to_string() }
    }
}

/// Every library error converts here once: its own [`Classify::is_input`] decides the status.
impl<E: Classify> From<E> for Failure {
    fn from(e: E) -> Self {
        if e.is_input() {
            Failure::input(e)
        } else {
            Failure::failed(e)
        }
    }
}

/// Writes one line to standard output, as `println!` would, but a closed pipe ends the command
/// quietly ([`Failure::reader_gone`]) instead of panicking.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::print_line(format_args!($($arg)*))?
    };
}

mod cmd;

fn print_line(line: std::fmt::Arguments) -> Result<(), Failure> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match writeln!(out, "{line}").and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Err(Failure::reader_gone()),
        Err(e) => Err(Failure::failed(format!("cannot write to standard output: {e}"))),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    lightsplit::accel::join_global_pool();
    remove_temporaries_on_signals();
    let result = match cli.command {
        Command::Render(args) => cmd::render::render_command(args),
        Command::Filter(args) => cmd::image::filter_command(args),
        Command::Merge(args) => cmd::merge::merge_command(args),
        Command::Compare(args) => cmd::image::compare_command(args),
        Command::Matte(args) => cmd::image::matte_command(args),
        Command::BenchAccel(args) => cmd::measure::bench_accel_command(args),
        Command::Converge(args) => cmd::measure::converge_command(args),
        Command::Stress(args) => cmd::measure::stress_command(args),
        Command::Info(args) => cmd::info::info_command(args),
        Command::BenchFeatures(args) => cmd::measure::bench_features_command(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) if f.message.is_empty() => ExitCode::from(f.code),
        Err(f) => {
            eprintln!("error: {}", printable(&f.message));
            ExitCode::from(f.code)
        }
    }
}

/// While a render runs, the first SIGINT, SIGTERM or SIGHUP sets this: the render ends after
/// its pass, and what it has is written.
static STOP: AtomicBool = AtomicBool::new(false);
/// Whether a signal now stops the render gracefully ([`STOP`]) instead of ending the process.
static GRACEFUL: AtomicBool = AtomicBool::new(false);
/// The signal that set [`STOP`] (0 for none).
static STOPPED_BY: AtomicI32 = AtomicI32::new(0);

/// On SIGINT, SIGTERM or SIGHUP: while a render runs ([`GRACEFUL`]), the first asks it to stop
/// after the pass under way ([`STOP`]) and the program to end, once it has written what was
/// rendered, with 128 + the signal's number. Otherwise (a second signal, or one outside a
/// render) removes the temporary file of a write under way (the output it would replace is left
/// as it was) and exits with 128 + the signal's number, the status a shell reports for a
/// process the signal stopped.
fn remove_temporaries_on_signals() {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    match signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) {
        Ok(mut signals) => {
            std::thread::spawn(move || {
                for signal in signals.forever() {
                    if GRACEFUL.load(Ordering::SeqCst) && !STOP.swap(true, Ordering::SeqCst) {
                        STOPPED_BY.store(signal, Ordering::SeqCst);
                        eprintln!(
                            "\nstopping after the pass under way, then writing what was rendered (again to stop now)"
                        );
                        continue;
                    }
                    // Held until the process ends: no write starts meanwhile.
                    let _held = film::remove_temporaries();
                    std::process::exit(128 + signal)
                }
            });
        }
        Err(e) => {
            eprintln!("warning: no signal handler ({e}): a stop during a write may leave a temporary file")
        }
    }
}

/// `text` with its control characters (a NUL or an ESC from a file name, say) escaped, so that
/// an error message cannot move the cursor, recolour or clear the terminal it is printed on.
fn printable(text: &str) -> String {
    text.chars()
        .map(|c| {
            if c.is_control() && c != '\n' && c != '\t' {
                c.escape_default().to_string()
            } else {
                c.to_string()
            }
        })
        .collect()
}

fn progress_bar(total: u64, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::new(total);
    if quiet || !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    } else if let Ok(style) =
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {percent}% (eta {eta})")
    {
        bar.set_style(style);
    }
    bar
}

/// Loads a scene and the filter setting its `[filter]` section asks for: a bad section is a bad
/// scene, whether or not the command filters. `defines` are `-D`'s parameters.
fn load_scene(path: &Path, defines: &cli::Defines) -> Result<(scene::Scene, Setting), Failure> {
    load_scene_with(path, &scene::LoadOptions { camera: None, defines: defines.define.clone() })
}

/// [`load_scene`] with the command line's choices (`render --camera`, `-D`).
fn load_scene_with(path: &Path, options: &scene::LoadOptions) -> Result<(scene::Scene, Setting), Failure> {
    let scene = scene::load_with(path, options)?;
    for note in &scene.notes {
        // A note that begins with its own place (a Mitsuba file's "file:line: ...") keeps it.
        match begins_with_place(note) {
            true => eprintln!("note: {note}"),
            false => eprintln!("note: {}: {note}", path.display()),
        }
    }
    let filter = Setting::of_scene(&scene)?;
    Ok((scene, filter))
}

/// Whether `note` begins "file:line: ", its first word (up to a space) ending in ":<digits>:".
fn begins_with_place(note: &str) -> bool {
    let head = note.split(' ').next().unwrap_or("");
    let Some(rest) = head.strip_suffix(':') else { return false };
    rest.rsplit_once(':').is_some_and(|(file, line)| {
        !file.is_empty() && !line.is_empty() && line.bytes().all(|b| b.is_ascii_digit())
    })
}

/// The output of a render of `scene` when none is named: its stem, as an EXR, here.
fn default_output(scene: &Path) -> PathBuf {
    let stem = scene.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "render".into());
    PathBuf::from(format!("{stem}.exr"))
}
