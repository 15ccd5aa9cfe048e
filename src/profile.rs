//! Where the step's time goes, pass by pass.

use std::time::Duration;

/// Accumulated wall-clock time per pass since the simulation started or was reset.
///
/// Force terms run fused in one parallel sweep (see [`crate::forces::ForceModel`]); their wall
/// time is that sweep's wall time split in proportion to the CPU time each term measured, so the
/// passes add up to the time spent stepping.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Profile {
    passes: Vec<PassTime>,
    /// Steps taken (each of `substeps` substeps).
    pub steps: u64,
    /// Wall time spent inside `step`, all passes and bookkeeping included.
    pub total: Duration,
    /// Wall time of all force sweeps so far; the step subtracts it from the integrator's time.
    pub force_time: Duration,
}

#[derive(Clone, Debug, PartialEq)]
pub struct PassTime {
    pub name: &'static str,
    pub time: Duration,
    /// How many times the pass ran (force terms run once per force evaluation).
    pub calls: u64,
}

impl Profile {
    pub fn add(&mut self, name: &'static str, time: Duration) {
        match self.passes.iter_mut().find(|p| p.name == name) {
            Some(entry) => {
                entry.time += time;
                entry.calls += 1;
            }
            None => self.passes.push(PassTime {
                name,
                time,
                calls: 1,
            }),
        }
    }

    /// Passes in the order they first ran.
    pub fn passes(&self) -> &[PassTime] {
        &self.passes
    }

    pub fn get(&self, name: &str) -> Option<&PassTime> {
        self.passes.iter().find(|p| p.name == name)
    }
}
