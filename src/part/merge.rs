//! Merging parts: checking that files are parts of one render, each once, and adding their
//! sums in the order of their indices.

use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::{read, read_header, Header};
use crate::film::Sums;

/// How many missing parts a merge names; the rest it counts.
pub const MISSING_NAMED: usize = 8;

/// A part to merge: its file (or, for a part held in memory, the name errors give it), its
/// header, and the sums of a part held in memory (a file's are read as the merge reaches it).
pub struct Named {
    pub path: PathBuf,
    pub header: Header,
    pub held: Option<Arc<Sums>>,
}

impl Named {
    /// The part file at `path`, by its header ([`read_header`]); an error names the file.
    pub fn read(path: &Path) -> Result<Named, MergeError> {
        let header = read_header(path).map_err(|e| MergeError(format!("{}: {e}", path.display())))?;
        Ok(Named { path: path.to_path_buf(), header, held: None })
    }

    /// A part held in memory (the Python module's), called `name` in errors.
    pub fn held(name: &str, header: Header, sums: Arc<Sums>) -> Named {
        Named { path: PathBuf::from(name), header, held: Some(sums) }
    }
}

/// Why parts cannot be merged: one line naming the files.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct MergeError(pub String);

/// The parts of a render that a merge lacks: how many, and the first few.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Missing {
    /// Of how many parts.
    pub of: u32,
    /// How many are missing.
    pub count: u32,
    /// The indices of the first [`MISSING_NAMED`] of them.
    pub first: Vec<u32>,
}

impl fmt::Display for Missing {
    /// `part 1/3`, `parts 1/8, 3/8`, or `parts 1/4096, ..., 8/4096 and 4087 more`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let named: Vec<String> = self.first.iter().map(|i| format!("{i}/{}", self.of)).collect();
        write!(f, "part{} {}", if self.count == 1 { "" } else { "s" }, named.join(", "))?;
        let more = self.count as usize - self.first.len();
        if more > 0 {
            write!(f, " and {more} more")?;
        }
        Ok(())
    }
}

/// Checks that `parts` are parts of one render, each once, and all of them unless
/// `allow_missing`; returns the part count and the missing parts. Nothing here is allocated or
/// done per part of the render, only per part given (a header may declare millions).
pub fn check(parts: &[Named], allow_missing: bool) -> Result<(u32, Missing), MergeError> {
    let first = parts.first().ok_or_else(|| MergeError("no parts to merge".into()))?;
    let (count, spp) = (first.header.part.count, first.header.spp);
    let different = |p: &Named, why: String| {
        MergeError(format!(
            "{} and {} are parts of different renders ({why})",
            p.path.display(),
            first.path.display()
        ))
    };
    for p in parts {
        let h = &p.header;
        if h.spp != spp {
            return Err(different(p, format!("of {} spp against {spp}", h.spp)));
        }
        if h.part.count != count {
            return Err(different(p, format!("{} parts against {count}", h.part.count)));
        }
        if h.key != first.header.key {
            return Err(different(
                p,
                format!("the scene files or settings differ: key {} against {}", h.key, first.header.key),
            ));
        }
    }
    let mut given: Vec<&Named> = parts.iter().collect();
    given.sort_by_key(|p| p.header.part.index);
    if let Some(pair) = given.windows(2).find(|w| w[0].header.part.index == w[1].header.part.index) {
        return Err(MergeError(format!(
            "{} and {} are both part {}: a part is merged once",
            pair[0].path.display(),
            pair[1].path.display(),
            pair[0].header.part
        )));
    }
    if let (Some(p), false) = (parts.iter().find(|p| !p.header.complete), allow_missing) {
        return Err(MergeError(format!(
            "{} is part {} stopped before its samples were all taken (a checkpoint): resume it \
             (`render --resume`), or merge what there is with --allow-missing",
            p.path.display(),
            p.header.part
        )));
    }
    // The gaps between the given indices, sorted: the first few named, all counted.
    let mut missing = Missing { of: count, count: count - given.len() as u32, first: Vec::new() };
    let mut next = 0;
    for index in given.iter().map(|p| p.header.part.index).chain([count]) {
        missing.first.extend((next..index).take(MISSING_NAMED - missing.first.len()));
        next = index + 1;
    }
    if missing.count > 0 && !allow_missing {
        return Err(MergeError(format!(
            "missing {missing} of {count} (--allow-missing merges what there is)"
        )));
    }
    Ok((count, missing))
}

/// Adds up the parts ([`check`]ed), read one at a time, in the order of their indices (so the
/// result does not depend on the order the files were named in); `each` is called after each.
pub fn merge(parts: &[Named], each: &dyn Fn()) -> Result<Sums, MergeError> {
    let mut order: Vec<&Named> = parts.iter().collect();
    order.sort_by_key(|p| p.header.part.index);
    let mut total: Option<Sums> = None;
    for p in order {
        let at = |e: String| MergeError(format!("{}: {e}", p.path.display()));
        let read_sums;
        let sums = match &p.held {
            Some(sums) => &**sums,
            None => {
                let (header, sums) = read(&p.path).map_err(at)?;
                if header != p.header {
                    return Err(at("the file changed while it was merged".into()));
                }
                read_sums = sums;
                &read_sums
            }
        };
        match &mut total {
            None => total = Some(sums.clone()),
            Some(t) => t.add(sums).map_err(at)?,
        }
        each();
    }
    total.ok_or_else(|| MergeError("no parts to merge".into()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn missing_parts_are_named_a_few_and_counted() {
        let few = Missing { of: 3, count: 1, first: vec![1] };
        assert_eq!(few.to_string(), "part 1/3");
        let many = Missing { of: 4096, count: 4095, first: (1..=MISSING_NAMED as u32).collect() };
        assert_eq!(
            many.to_string(),
            "parts 1/4096, 2/4096, 3/4096, 4/4096, 5/4096, 6/4096, 7/4096, 8/4096 and 4087 more"
        );
    }
}
