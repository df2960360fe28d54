//! Which part a process renders: `I/N` from the command line, or from a batch scheduler's
//! environment (a Slurm job array, a Kubernetes Indexed Job).

use std::ffi::OsString;

use crate::render::Part;

/// `I/N` with I < N.
pub fn parse_part(text: &str) -> Result<Part, String> {
    let bad = || format!("`{text}` is not a part I/N (0 <= I < N)");
    let (i, n) = text.split_once('/').ok_or_else(bad)?;
    let (index, count): (u32, u32) =
        (i.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
    if count == 0 || index >= count {
        return Err(bad());
    }
    Ok(Part { index, count })
}

/// The part a batch scheduler gives this process, from its environment (`var` looks a variable
/// up): a Slurm job array (`SLURM_ARRAY_TASK_ID` less `SLURM_ARRAY_TASK_MIN`, of
/// `SLURM_ARRAY_TASK_COUNT`) or a Kubernetes Indexed Job (`JOB_COMPLETION_INDEX`, of
/// `LIGHTSPLIT_PART_COUNT`, which the Job sets to its completions).
pub fn part_from_scheduler(var: impl Fn(&str) -> Option<OsString>) -> Result<Part, String> {
    let number = |name: &str, value: OsString| -> Result<u32, String> {
        value.to_str().and_then(|v| v.trim().parse::<u32>().ok()).ok_or_else(|| {
            format!("{name}={} is not a number (a whole number from 0)", value.to_string_lossy())
        })
    };
    let (index, count) = if let (Some(id), Some(count)) =
        (var("SLURM_ARRAY_TASK_ID"), var("SLURM_ARRAY_TASK_COUNT"))
    {
        let id = number("SLURM_ARRAY_TASK_ID", id)?;
        let min = var("SLURM_ARRAY_TASK_MIN").map_or(Ok(0), |m| number("SLURM_ARRAY_TASK_MIN", m))?;
        let count = number("SLURM_ARRAY_TASK_COUNT", count)?;
        let index = id.checked_sub(min).ok_or_else(|| {
            format!("SLURM_ARRAY_TASK_ID={id} is below SLURM_ARRAY_TASK_MIN={min}: not a task of this array")
        })?;
        if index >= count {
            return Err(format!(
                "SLURM_ARRAY_TASK_ID={id} less SLURM_ARRAY_TASK_MIN={min} is {index}, past the last of \
                 SLURM_ARRAY_TASK_COUNT={count} parts (an array with a step, such as 1-9:2, does not \
                 split a render)"
            ));
        }
        (index, count)
    } else if let Some(index) = var("JOB_COMPLETION_INDEX") {
        let count = var("LIGHTSPLIT_PART_COUNT")
            .ok_or("JOB_COMPLETION_INDEX is set but LIGHTSPLIT_PART_COUNT (the Job's completions) is not")?;
        let (index, count) =
            (number("JOB_COMPLETION_INDEX", index)?, number("LIGHTSPLIT_PART_COUNT", count)?);
        if index >= count {
            return Err(format!(
                "JOB_COMPLETION_INDEX={index} is past the last of LIGHTSPLIT_PART_COUNT={count} parts"
            ));
        }
        (index, count)
    } else {
        return Err("no scheduler found (SLURM_ARRAY_TASK_ID and SLURM_ARRAY_TASK_COUNT, or \
                    JOB_COMPLETION_INDEX and LIGHTSPLIT_PART_COUNT)"
            .into());
    };
    Ok(Part { index, count })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scheduler's variables, as `part_from_scheduler` looks them up.
    fn env<'a>(vars: &'a [(&'a str, &'a [u8])]) -> impl Fn(&str) -> Option<OsString> + 'a {
        use std::os::unix::ffi::OsStrExt;
        move |name| {
            vars.iter().find(|(n, _)| *n == name).map(|(_, v)| std::ffi::OsStr::from_bytes(v).to_owned())
        }
    }

    #[test]
    fn the_scheduler_gives_the_part_or_says_which_variable_is_wrong() {
        let slurm = |id: &'static [u8]| {
            part_from_scheduler(env(&[
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_MIN", b"1"),
                ("SLURM_ARRAY_TASK_COUNT", b"4"),
            ]))
        };
        assert_eq!(slurm(b"3"), Ok(Part { index: 2, count: 4 }));
        assert!(slurm(b"0").is_err_and(|e| e.contains("below SLURM_ARRAY_TASK_MIN=1")));
        assert!(slurm(b"5").is_err_and(|e| e.contains("past the last")));
        assert!(slurm(b"\xff").is_err_and(|e| e.contains("SLURM_ARRAY_TASK_ID=\u{fffd} is not a number")));
        let k8s =
            part_from_scheduler(env(&[("JOB_COMPLETION_INDEX", b"2"), ("LIGHTSPLIT_PART_COUNT", b"3")]));
        assert_eq!(k8s, Ok(Part { index: 2, count: 3 }));
        assert!(part_from_scheduler(env(&[("JOB_COMPLETION_INDEX", b"2")]))
            .is_err_and(|e| e.contains("LIGHTSPLIT_PART_COUNT")));
        assert!(part_from_scheduler(env(&[])).is_err_and(|e| e.contains("no scheduler found")));
    }
}
