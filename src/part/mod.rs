//! Part files: a render's per-pixel sums ([`Accumulated`]) in an EXR, what a render on many
//! machines leaves on each and what `lightsplit merge` adds up; also a checkpoint's file, from
//! which a render resumes.
//!
//! A part file is an ordinary EXR whose `R`, `G`, `B` and `A` are the part's own image (so any
//! viewer shows it), with the sums under `sums.` (the layers of a render's EXR, as sums: see
//! [`Accumulated::film`]; the sums of squares, in f64, as two 32-bit words each) and each
//! pixel's sample count in `samples.N`. Its header says which render it belongs to (the run
//! key: a hash of the scene's files and of every option that changes a sample), which part it
//! is and which samples it holds.
//!
//! A part file is input like any other: [`read`] refuses one whose sums no render could have
//! made (NaN, negative light, more samples than its part has, counts that do not fit its
//! sums), so a damaged or edited file is an error naming it rather than a wrong image.
//!
//! The filter is not linear (the median, the edge stops), so parts are never filtered: the merge
//! adds the sums, then filters once.

mod file;
mod key;
mod merge;
mod resume;
mod schedule;

pub use file::{read, read_header, write, Header};
pub use key::{run_key, RunKey};
pub use merge::{check, merge, MergeError, Missing, Named, MISSING_NAMED};
pub use resume::read_checkpoint;
pub use schedule::{parse_part, part_from_scheduler};
