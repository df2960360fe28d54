//! Run keys: a hash that says whether two files come from one render (parts, checkpoints) or
//! one measurement (`converge`'s rows and cached reference). One hash for both, so that what
//! counts as "the same input" is decided once.

use std::path::Path;

use crate::math::Fnv;
use crate::render::RenderOptions;
use crate::scene::Scene;

/// A run key being built: FNV-1a over the contents of files and over the settings written to
/// it, ended by the program's version ([`RunKey::finish`]).
#[derive(Default)]
pub struct RunKey(Fnv);

impl RunKey {
    /// The key of the scene's inputs: the contents of every file the scene was read from (the
    /// scene file, its meshes, their material libraries, image textures).
    pub fn of_scene(scene: &Scene) -> Result<RunKey, String> {
        let mut key = RunKey::default();
        for path in &scene.inputs {
            key.file(path)?;
        }
        for (name, value) in &scene.parameters {
            key.bytes(format!("{}={}\0", name.len(), name).as_bytes());
            key.bytes(value.as_bytes());
        }
        Ok(key)
    }

    /// Adds a file's contents (its length first, so that two files cannot run together).
    pub fn file(&mut self, path: &Path) -> Result<(), String> {
        let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
        self.0.write(&(bytes.len() as u64).to_le_bytes());
        self.0.write(&bytes);
        Ok(())
    }

    /// Adds numbers.
    pub fn numbers(&mut self, values: &[u64]) {
        for v in values {
            self.0.write(&v.to_le_bytes());
        }
    }

    /// Adds bytes (a name, a tag).
    pub fn bytes(&mut self, bytes: &[u8]) {
        self.0.write(bytes);
    }

    /// The key: the hash with the program's version added, as 16 hex digits.
    pub fn finish(mut self) -> String {
        self.0.write(env!("CARGO_PKG_VERSION").as_bytes());
        format!("{:016x}", self.0 .0)
    }
}

/// The key of a render: its scene's inputs ([`RunKey::of_scene`]) and every option that changes
/// a sample: the image size, the samples per pixel, the path length, the seed, the sampler,
/// the light sampler, guiding, what the integrator computes, adaptive sampling, the AOVs, and the program's version. Not the backend
/// (Embree and the BVH give the same samples up to float rounding), the threads, or which part.
pub fn run_key(scene: &Scene, options: &RenderOptions) -> Result<String, String> {
    let mut key = RunKey::of_scene(scene)?;
    let o = options;
    key.numbers(&[o.width as u64, o.height as u64, o.spp as u64, o.max_depth as u64, o.seed]);
    key.bytes(o.sampler.name().as_bytes());
    key.bytes(o.light_sampler.name().as_bytes());
    key.bytes(o.guiding.name().as_bytes());
    key.bytes(&[o.features.bits()]);
    key.bytes(&o.adaptive.map_or(u32::MAX, f32::to_bits).to_le_bytes());
    for aov in &o.aovs {
        key.bytes(format!("{}={}\0{}\0", aov.name.len(), aov.name, aov.lpe).as_bytes());
    }
    if o.cryptomatte {
        // After the AOVs, whose entries start with a digit.
        key.bytes(b"+cryptomatte");
    }
    Ok(key.finish())
}
