//! The energy audit: where the work done on the bodies went.

/// Energy bookkeeping, joules. `balance()` is constant when the audit closes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    pub kinetic: f64,
    pub elastic: f64,
    pub friction: f64,
    pub damping: f64,
    pub gravity_work: f64,
    pub wall_work: f64,
}

impl Energy {
    /// Kinetic + elastic + dissipated - work done on the system: constant in a closed audit.
    pub fn balance(&self) -> f64 {
        self.kinetic + self.elastic + self.friction + self.damping
            - self.gravity_work
            - self.wall_work
    }
}
