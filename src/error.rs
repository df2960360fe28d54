//! What every error of the library says beyond its message: whether the input was bad (a scene
//! file, an argument, an image or part file, an output path: exit status 2) or the work failed
//! on good input (status 1). Each layer has its own error type and implements this once; the
//! command line converts any of them in one place.

/// An error that knows whose fault it is.
pub trait Classify: std::fmt::Display {
    /// Whether the input was bad (rather than the work failing).
    fn is_input(&self) -> bool;
}

/// Bad input, said in a sentence: for the few checks whose only failure is the input's.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct InputError(pub String);

/// `Classify` for error types that are always, or never, the input's fault.
macro_rules! classified {
    ($is_input:literal: $($t:ty),+ $(,)?) => {
        $(impl Classify for $t {
            fn is_input(&self) -> bool {
                $is_input
            }
        })+
    };
}

// A bad sentence, a scene file or an image that cannot be read, parts that do not make one render (or a
// part file that is not one): the input's. A backend that cannot build a valid scene, threads
// that cannot start, a stress row that cannot run: a failure of the program or the machine.
classified!(true: InputError, crate::scene::SceneError, crate::film::ReadError, crate::part::MergeError);
classified!(false: crate::accel::AccelError, crate::stress::StressError);

impl Classify for crate::converge::ConvergeError {
    fn is_input(&self) -> bool {
        matches!(self, crate::converge::ConvergeError::Input(_))
    }
}
