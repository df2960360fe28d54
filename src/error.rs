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

impl Classify for InputError {
    fn is_input(&self) -> bool {
        true
    }
}

impl Classify for crate::scene::SceneError {
    /// A scene file that cannot be read is always the input's fault.
    fn is_input(&self) -> bool {
        true
    }
}

impl Classify for crate::part::MergeError {
    /// Parts that do not make one render, or a part file that is not one.
    fn is_input(&self) -> bool {
        true
    }
}

impl Classify for crate::converge::ConvergeError {
    fn is_input(&self) -> bool {
        matches!(self, crate::converge::ConvergeError::Input(_))
    }
}

impl Classify for crate::accel::AccelError {
    /// A backend that cannot build a valid scene, or threads that cannot start.
    fn is_input(&self) -> bool {
        false
    }
}

impl Classify for crate::stress::StressError {
    /// A row that cannot run is a bug of the suite or the machine.
    fn is_input(&self) -> bool {
        false
    }
}
