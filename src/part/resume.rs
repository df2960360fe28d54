//! Resuming: the checkpoint a render goes on from, checked against the render.

use std::path::Path;

use super::{read, read_header, run_key};
use crate::film::Sums;
use crate::render::RenderOptions;
use crate::scene::Scene;

/// Reads the part file a render resumes from, `path`, for a render of `scene` with `options`
/// (whose part, spp and key it must have). A checkpoint holds the buffers its own output
/// needed; when it holds more than this render's output needs (written for an EXR, resumed to
/// a PNG), `options` takes them on, since they change no sample of the beauty.
pub fn read_checkpoint(path: &Path, scene: &Scene, options: &mut RenderOptions) -> Result<Sums, String> {
    let header = read_header(path).map_err(|e| {
        format!(
            "a resume file is a part file (`.part.exr`, an EXR that --part, --checkpoint or a \
             stopped render writes): {e}"
        )
    })?;
    if header.part != options.part || header.spp != options.spp {
        return Err(format!(
            "it holds part {} of {} spp, this render part {} of {} spp",
            header.part, header.spp, options.part, options.spp
        ));
    }
    if header.adaptive.is_some() {
        return Err("it is a part of an adaptive render, which cannot be resumed".into());
    }
    let (header, sums) = read(path)?;
    if header.key == run_key(scene, options)? {
        return Ok(sums);
    }
    let (split, guides) = (sums.film.has_split(), sums.film.has_guides());
    let with_its_buffers = RenderOptions {
        features: crate::render::Features { split, guides, ..options.features },
        ..options.clone()
    };
    if header.key != run_key(scene, &with_its_buffers)? {
        return Err(
            "it is not a checkpoint of this render: the scene files or the settings that change a sample \
             differ (size, seed, path length, sampler, features)"
                .into(),
        );
    }
    let lacking: Vec<&str> = [
        (options.features.split && !split, "the component split"),
        (options.features.guides && !guides, "the guide buffers"),
    ]
    .into_iter()
    .filter_map(|(lacks, what)| lacks.then_some(what))
    .collect();
    if !lacking.is_empty() {
        return Err(format!(
            "it was written for an output that needs fewer buffers (a PNG, say) and holds no {}, which this \
             output needs: resume it to such an output",
            lacking.join(" and no ")
        ));
    }
    options.features = with_its_buffers.features;
    Ok(sums)
}
