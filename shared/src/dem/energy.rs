//! The energy audit: where the work done on the bodies went.

/// Energy bookkeeping, joules. `balance()` is constant when the audit closes.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// Kinetic energy of the bodies (translation and rotation).
    pub kinetic: f64,
    /// Energy stored in the contacts.
    pub elastic: f64,
    /// Dissipated by slip, accumulated.
    pub friction: f64,
    /// Taken by the bodies' local damping, accumulated.
    pub damping: f64,
    /// Work of gravity on the bodies, accumulated.
    pub gravity_work: f64,
    /// Work of moving rigid walls on the bodies (and on membranes through their pinned nodes),
    /// accumulated; a membrane's contacts with the bodies are internal.
    pub wall_work: f64,
    /// Kinetic energy of the membranes' nodes.
    pub membrane_kinetic: f64,
    /// Elastic energy of the membranes.
    pub membrane_elastic: f64,
    /// Taken by the membranes' local damping, accumulated.
    pub membrane_damping: f64,
    /// Work of the membranes' pressure, accumulated.
    pub pressure_work: f64,
}

impl Energy {
    /// Kinetic + elastic + dissipated - work done on the system: constant in a closed audit.
    pub fn balance(&self) -> f64 {
        self.kinetic + self.elastic + self.friction + self.damping
            - self.gravity_work
            - self.wall_work
            + (self.membrane_kinetic + self.membrane_elastic + self.membrane_damping
                - self.pressure_work)
    }
}
