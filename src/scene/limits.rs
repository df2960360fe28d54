//! The bounds on what a scene file or the command line may ask for: one rule for both, so
//! that neither runs a job that cannot end or cannot fit.

use crate::error::InputError;

/// The largest image side, in pixels.
pub const MAX_SIZE: u32 = 1 << 16;
/// The most pixels of an image, rendered or read (an EXR, an environment map): 2^30, a
/// 32768x32768 or 65536x16384 image, whose RGB floats alone take 12 GiB.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 30;
/// The most samples per pixel.
pub const MAX_SPP: u32 = 1 << 24;
/// The most scattering events per path (as pbrt and Mitsuba cap theirs): a closed mirror box
/// would otherwise never end.
pub const MAX_DEPTH: u32 = 1024;
/// The largest emission of a surface (a shape's `emission`, an `.mtl`'s `Ke`): what a camera
/// ray sees of it is a finite sample that the film sums in 32-bit floats (its squares in 64),
/// and the film must stay finite (a value of 3e38 made an EXR of infinities). Real scenes are
/// many orders of magnitude below. Lights are not bounded: a sample their power overflows is
/// infinite, and dropped and counted as every non-finite sample is.
pub const MAX_EMISSION: f32 = 1e12;
/// The widest filter kernel side (63x63).
pub const MAX_KERNEL: usize = 63;
/// The largest scene file read, 16 MiB: its parsed form takes about a hundred times its size,
/// and meshes belong in their own files.
pub const MAX_SCENE_BYTES: u64 = 16 << 20;
/// The largest mesh or image texture read, unless `LIGHTSPLIT_MAX_INPUT_BYTES` says otherwise.
pub const MAX_INPUT_BYTES: u64 = 4 << 30;

/// The most elements (vertices, indices, faces) one glTF accessor or PLY element may declare:
/// 2^28, 3 GiB of f32 positions. A count is also checked against the bytes that can back it
/// and the memory available before anything is allocated.
pub const MAX_ELEMENTS: u64 = 1 << 28;

/// The farthest a shape may reach from the camera, in scene units. The triangle tests of both
/// backends multiply coordinates in f32, whose products overflow from about 1.8e19: a vertex at
/// 3e38 wrote an infinite depth through the BVH while Embree dropped its triangle, and a glTF
/// placed at a scale of 1e20 vanished on both. 1e15 keeps the products eight orders inside f32.
pub const MAX_COORDINATE: f32 = 1e15;

/// The most worker threads: 16 a core (at least 64). More only costs memory and start-up.
pub fn max_threads() -> usize {
    16 * std::thread::available_parallelism().map_or(4, usize::from).max(4)
}

/// The largest mesh or texture read: [`MAX_INPUT_BYTES`], or `LIGHTSPLIT_MAX_INPUT_BYTES`.
pub fn max_input_bytes() -> u64 {
    std::env::var("LIGHTSPLIT_MAX_INPUT_BYTES")
        .ok()
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or(MAX_INPUT_BYTES)
}

/// Checks a scene file before it is read: a regular file of at most [`MAX_SCENE_BYTES`].
pub fn check_scene_file(path: &std::path::Path) -> Result<(), String> {
    check_file(path, MAX_SCENE_BYTES, "put meshes in OBJ files")
}

/// Checks a mesh or an image texture before it is read: a regular file of at most
/// [`max_input_bytes`].
pub fn check_input_file(path: &std::path::Path) -> Result<(), String> {
    check_file(path, max_input_bytes(), "LIGHTSPLIT_MAX_INPUT_BYTES raises it")
}

/// Checks that `path` is a regular file of at most `max` bytes, before it is read: a device
/// (`/dev/zero`), a FIFO or a directory would be read without end or not at all. `hint` says
/// what to do about a file too large.
fn check_file(path: &std::path::Path, max: u64, hint: &str) -> Result<(), String> {
    let meta = std::fs::metadata(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    if !meta.is_file() {
        return Err(format!("{} is not a regular file", path.display()));
    }
    if meta.len() > max {
        return Err(format!(
            "{} is {} bytes, over the {max} read at most ({hint})",
            path.display(),
            meta.len()
        ));
    }
    Ok(())
}

/// The memory a render of `width` x `height` needs at most, in bytes: the film's buffers (eight
/// colour layers and eight scalar ones), the adaptive tiles' moments, a filter's working
/// planes and the output's encoding, about 400 bytes a pixel.
pub fn render_bytes(width: u32, height: u32) -> u64 {
    width as u64 * height as u64 * 400
}

/// The memory this process can still have: the machine's available memory (`MemAvailable` of
/// `/proc/meminfo`), or what is left of the process's address-space limit (`ulimit -v`, less
/// the `VmSize` already mapped) if that is lower; `None` if neither is known.
pub fn available_bytes() -> Option<u64> {
    let machine = (|| {
        let text = std::fs::read_to_string("/proc/meminfo").ok()?;
        let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
        let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        Some(kib * 1024)
    })();
    let limit = (|| {
        let text = std::fs::read_to_string("/proc/self/limits").ok()?;
        let line = text.lines().find(|l| l.starts_with("Max address space"))?;
        let limit = line.split_whitespace().nth(3)?.parse::<u64>().ok()?;
        let status = std::fs::read_to_string("/proc/self/status").ok()?;
        let size = status.lines().find(|l| l.starts_with("VmSize:"))?;
        let kib: u64 = size.split_whitespace().nth(1)?.parse().ok()?;
        Some(limit.saturating_sub(kib * 1024))
    })();
    match (machine, limit) {
        (Some(m), Some(l)) => Some(m.min(l)),
        (m, l) => m.or(l),
    }
}

/// Refuses `need` bytes for `what` (a render, an image's pixels, an accessor's elements) when
/// the memory available ([`available_bytes`]) cannot hold them.
pub fn check_memory(need: u64, what: &str) -> Result<(), String> {
    match available_bytes() {
        Some(have) if need > have => Err(format!(
            "{what} needs about {:.2} GiB and {:.2} GiB is available",
            need as f64 / (1u64 << 30) as f64,
            have as f64 / (1u64 << 30) as f64
        )),
        _ => Ok(()),
    }
}

/// Refuses a render that would not fit in the memory available.
/// `layer_bytes` a pixel more are the layers a render adds to the film's ([`render_bytes`]):
/// AOVs, Cryptomatte mattes.
pub fn check_render_memory(width: u32, height: u32, layer_bytes: u64) -> Result<(), InputError> {
    let bytes = render_bytes(width, height) + width as u64 * height as u64 * layer_bytes;
    check_memory(bytes, &format!("a {width}x{height} render"))
        .map_err(|e| InputError(format!("{e}: render smaller")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_cap_are_read() {
        let dir = tempfile::tempdir().expect("tempdir");
        let file = dir.path().join("f.obj");
        std::fs::write(&file, [0u8; 100]).expect("write");
        assert_eq!(check_file(&file, 100, ""), Ok(()));
        assert!(check_file(&file, 99, "").is_err_and(|e| e.contains("over the 99")));
        assert!(check_file(dir.path(), 1 << 20, "").is_err_and(|e| e.contains("not a regular file")));
        assert!(check_file(std::path::Path::new("/dev/zero"), 1 << 20, "")
            .is_err_and(|e| e.contains("not a regular file")));
        assert!(check_file(&dir.path().join("gone"), 1 << 20, "").is_err());
    }

    #[test]
    fn a_render_larger_than_memory_is_refused() {
        let have = available_bytes().expect("/proc/meminfo");
        assert!(check_render_memory(64, 64, 0).is_ok());
        assert!(check_render_memory(64, 64, have / 4096).is_err(), "the layers' bytes count");
        // The largest image allowed needs 1.7 TB.
        assert!(render_bytes(MAX_SIZE, MAX_SIZE) > have);
        assert!(check_render_memory(MAX_SIZE, MAX_SIZE, 0).is_err_and(|e| e.0.contains("GiB is available")));
    }
}
