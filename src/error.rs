//! The one error type of the core. Every fallible public call returns it; nothing panics on
//! bad input. The Python binding maps each variant onto the exception a user would catch.

use std::fmt;

/// What went wrong, with the name of the parameter at fault.
#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A value of the right type that makes no sense (negative stiffness, `dt = nan`, an unknown
    /// scene key, a wrong array shape). Maps to `ValueError`.
    InvalidValue { name: String, message: String },
    /// A value of the wrong type (a string where a number belongs). Maps to `TypeError`.
    InvalidType { name: String, message: String },
    /// A particle index outside `0..len`. Maps to `IndexError`.
    IndexOutOfRange {
        name: String,
        index: i64,
        len: usize,
    },
    /// A step went wrong (see [`Trouble`]) and, where the scene asked for it, retrying it with
    /// more substeps did not help; the simulation was rolled back to the state before step
    /// `step`, so `steps()` reads `step - 1`. Maps to `rustcloth.SimulationDiverged`.
    Diverged {
        step: u64,
        particle: usize,
        reason: Trouble,
        /// Most substeps the step was tried with.
        substeps: u32,
    },
    /// A bug in rustcloth: the core panicked. The simulation was put back at the start of the
    /// step (or call) that panicked and stays usable. Maps to `rustcloth.InternalError`.
    Internal { message: String },
    /// A long `step` or `advance` was interrupted (Ctrl-C) at a step boundary, after `steps`
    /// steps. The binding raises the interrupt itself (`KeyboardInterrupt`).
    Interrupted { steps: u64 },
}

/// How a step went wrong.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Trouble {
    /// A position or velocity became infinite or NaN.
    NonFinite,
    /// A spring grew longer than the watchdog's `max_stretch` times its rest length; `stretch`
    /// is the ratio `l / L` of the first such spring found.
    Overstretched { stretch: f32, limit: f32 },
    /// With self-collision and an integrator past its estimated stable step, `share` of the
    /// cloth's edges changed length by more than half its spacing within one substep: the step
    /// no longer resolves the cloth's motion, a runaway the pass would otherwise hide by
    /// holding the cloth apart instead of letting it reach infinity.
    Unresolved { share: f32 },
    /// The self-collision cap stopped `stopped` vertices in one substep: a cluster of contacts
    /// moving together farther in a substep than the cap lets a pair close, held at the
    /// substep's start while the cloth around it moves on. Always retried with more substeps,
    /// whatever `watchdog.on_trouble` says, and accepted as it is at the most the watchdog
    /// allows it (see `stepper/watchdog.rs`), so it reaches the user only by name.
    Cascade { stopped: u64 },
    /// The step panicked (a bug): never retried, reported as [`Error::Internal`].
    Panicked,
}

impl Trouble {
    /// Whether this is [`Trouble::Cascade`], which every scene retries.
    pub fn is_cascade(&self) -> bool {
        matches!(self, Trouble::Cascade { .. })
    }

    /// Its name in Python (`SimulationDiverged.reason`).
    pub fn name(&self) -> &'static str {
        match self {
            Trouble::NonFinite => "non_finite",
            Trouble::Overstretched { .. } => "overstretched",
            Trouble::Unresolved { .. } => "unresolved",
            Trouble::Cascade { .. } => "cascade",
            Trouble::Panicked => "panicked",
        }
    }
}

impl Error {
    pub(crate) fn value(name: impl Into<String>, message: impl Into<String>) -> Self {
        Error::InvalidValue {
            name: name.into(),
            message: message.into(),
        }
    }

    pub(crate) fn index(name: impl Into<String>, index: i64, len: usize) -> Self {
        Error::IndexOutOfRange {
            name: name.into(),
            index,
            len,
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::InvalidValue { name, message } | Error::InvalidType { name, message } => {
                write!(f, "{name}: {message}")
            }
            Error::IndexOutOfRange { name, index, len } => {
                write!(
                    f,
                    "{name}: index {index} is out of range for {len} particles"
                )
            }
            Error::Diverged {
                step,
                particle,
                reason,
                substeps,
            } => {
                write!(f, "the simulation diverged at step {step}: ")?;
                match reason {
                    Trouble::NonFinite => write!(f, "particle {particle} became non-finite")?,
                    Trouble::Overstretched { stretch, limit } => write!(
                        f,
                        "a spring at particle {particle} stretched to {stretch:.3} times its rest \
                         length, beyond the watchdog's max_stretch = {limit}"
                    )?,
                    Trouble::Unresolved { share } => write!(
                        f,
                        "{:.1} % of the edges, particle {particle}'s first, changed length by \
                         more than half the cloth's spacing within one substep (an integrator \
                         past its stable step)",
                        100.0 * share
                    )?,
                    Trouble::Cascade { stopped } => write!(
                        f,
                        "the self-collision pass stopped {stopped} particles in one substep"
                    )?,
                    Trouble::Panicked => write!(f, "the solver panicked")?,
                }
                write!(
                    f,
                    " with {substeps} substep(s); the state before that step was restored (try a \
                     smaller dt, more substeps, watchdog.on_trouble = \"substep\", strain \
                     limiting, or the implicit_euler integrator)"
                )
            }
            Error::Internal { message } => write!(
                f,
                "internal error (a bug in rustcloth, please report it): {message}; the \
                 simulation was put back where the call started"
            ),
            Error::Interrupted { steps } => write!(f, "interrupted after {steps} step(s)"),
        }
    }
}

impl std::error::Error for Error {}

pub type Result<T> = std::result::Result<T, Error>;

/// Checks that `value` is finite and, where `positive`, strictly above zero, or at least zero
/// otherwise. Shared by scene validation and the setters.
pub(crate) fn check_scalar<T>(name: &str, value: T, bound: Bound) -> Result<()>
where
    T: Into<f64> + Copy + fmt::Display,
{
    let x: f64 = value.into();
    let ok = x.is_finite()
        && match bound {
            Bound::Any => true,
            Bound::NonNegative => x >= 0.0,
            Bound::Positive => x > 0.0,
        };
    if !ok {
        let want = match bound {
            Bound::Any => "a finite number",
            Bound::NonNegative => "a finite number >= 0",
            Bound::Positive => "a finite number > 0",
        };
        return Err(Error::value(name, format!("must be {want}, got {value}")));
    }
    // Scene values are f64 but the solver runs in f32: beyond f32's range is as unusable as
    // infinity, and a positive value that rounds to zero is zero.
    if x.abs() > f32::MAX as f64 {
        return Err(Error::value(
            name,
            format!("must be within f32 range (|x| <= 3.4e38), got {value}"),
        ));
    }
    if matches!(bound, Bound::Positive) && (x as f32) == 0.0 {
        return Err(Error::value(
            name,
            format!("must be at least the smallest float32 (1.4e-45), got {value}"),
        ));
    }
    Ok(())
}

/// Checks that `values` holds `n` finite vectors (positions, velocities).
pub(crate) fn check_vec3s(name: &str, values: &crate::soa::Vec3s, n: usize) -> Result<()> {
    if values.len() != n || values.y.len() != n || values.z.len() != n {
        return Err(Error::value(
            name,
            format!("must hold {n} vectors, got {}", values.len()),
        ));
    }
    if let Some(p) = (0..n).find(|&p| !values.get(p).is_finite()) {
        return Err(Error::value(
            name,
            format!("row {p} is not finite: {:?}", values.get(p).to_array()),
        ));
    }
    Ok(())
}

/// Checks each component of a vector with [`check_scalar`].
pub(crate) fn check_vector(name: &str, value: &[f64], bound: Bound) -> Result<()> {
    for (axis, &c) in value.iter().enumerate() {
        check_scalar(&format!("{name}[{axis}]"), c, bound)?;
    }
    Ok(())
}

#[derive(Clone, Copy, Debug)]
pub(crate) enum Bound {
    Any,
    NonNegative,
    Positive,
}
