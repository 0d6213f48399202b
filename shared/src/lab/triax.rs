//! The drained conventional triaxial test with a flexible membrane (the `triax` tool).
//!
//! From a specimen made by [`crate::lab::pack`] in a cylinder between two platens:
//! 1. **Membrane.** The rigid cylinder is swapped for a membrane ([`crate::dem::membrane`]): a
//!    triangulated cylinder, its facets no larger than `edge` (by default the smallest
//!    particle's size), just outside the cylinder's facets (its chords on the cylinder's
//!    circle, so no particle overlaps it), its end rings sealed to the platens, the
//!    confining pressure on its outer side. With the rigid boundary ([`Boundary::Rigid`]) the
//!    cylinder stays, and PFC's servo moves its radius each step so that its contacts' outward
//!    stress is the pressure.
//! 2. **Consolidation.** The platens follow PFC's servo (without a rest band) so that the
//!    specimen's own vertical stress is the pressure the membrane holds on the side
//!    ([`Triax::held_stresses`]), until, at the end of a block of `balance_window` steps, both
//!    are within `tolerance` of it and the block's mean unbalanced-force ratio of the
//!    load-bearing bodies is below `unbalanced`: isotropic consolidation on the membrane.
//! 3. **Loading.** The platens approach each other at a constant logarithmic strain rate
//!    (each at half the speed `rate x H`), the confining pressure held on the membrane, until
//!    the axial strain `ln(H0 / H)` reaches `final_strain`. A measurement ([`Measure`]) every
//!    `every` of strain, a frame (the whole state) every `frame_every`, at the start of loading
//!    and at the end.
//!
//! Inertia: unless `inertia_scaling` is off, every body's mass is scaled as in the preparation
//! ([`crate::lab::inertia::scale_inertia`]), and the states written keep the scaled masses (a
//! restart continues the same dynamics). The membrane's nodes get a mass that makes their
//! critical step, against the contacts' `kn` and the membrane's own stiffness, the bodies'
//! ([`node_mass`]).

use crate::dem::contacts::{Contacts, Partner};
use crate::dem::membrane::{Guide, Membrane, Pin, Sheet};
use crate::dem::parallel::on_pool;
use crate::dem::wall::{Wall, WallKind};
use crate::dem::world::World;
use crate::geometry::mass::equivalent_diameter;
use crate::lab::boundary::{container, Bounds, Section, WallGeometry, BOTTOM, SIDE, TOP};
use crate::lab::inertia::scale_inertia;
use crate::lab::servo::{servo, set_speeds, wall_gain, ServoLaw};
use crate::math::{basis, cube, Vec3};
use crate::micro::stress::{contact_stress, coordination, invariants, symmetric_components};
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;
use thiserror::Error;

/// The default [`Params::ramp`]: full speed at 0.2 % of strain, where on a paper-scale
/// specimen at 0.5 /s q no longer depends on how the platens started (docs/models/triax.md).
pub const RAMP: f64 = 2e-3;
/// The default [`Params::opening`]: the first measurement after the start at 1/32 of `every`.
pub const OPENING: u32 = 5;
/// The default [`Params::balance_window`], steps.
pub const BALANCE_WINDOW: u64 = 500;

fn default_balance_window() -> u64 {
    BALANCE_WINDOW
}

/// The specimen's lateral boundary.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Boundary {
    /// A flexible membrane under the cell pressure (the paper's).
    #[default]
    Membrane,
    /// The pack's rigid cylinder, its radius on PFC's servo so that its contacts' outward
    /// stress is the cell pressure (PFC's and Yade's usual triaxial test).
    Rigid,
}

impl std::str::FromStr for Boundary {
    type Err = String;

    fn from_str(s: &str) -> Result<Boundary, String> {
        match s {
            "membrane" => Ok(Boundary::Membrane),
            "rigid" => Ok(Boundary::Rigid),
            _ => Err(format!("'{s}' is not a boundary: membrane or rigid")),
        }
    }
}

/// How to run the test (SI units). Defaults: the paper's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Confining pressure, Pa (on the lateral boundary, and on the platens during
    /// consolidation).
    pub pressure: f64,
    /// The lateral boundary (absent, as in streams written before it was a setting: the
    /// membrane). The membrane's settings below are unused with the rigid one.
    #[serde(default)]
    pub boundary: Boundary,
    /// Axial strain `ln(H0 / H)` at which loading ends.
    pub final_strain: f64,
    /// Axial strain rate during loading, 1/s.
    pub rate: f64,
    /// The membrane's Young's modulus (Pa), Poisson's ratio and thickness (m).
    pub young: f64,
    pub poisson: f64,
    pub thickness: f64,
    /// The membrane's largest facet edge, m (`None`: the smallest particle's size).
    pub edge: Option<f64>,
    /// Stiffness of the particles' contacts with the membrane, N/m^3 (a Winkler foundation:
    /// pressure over penetration; `None`: the sheet's own, `young / thickness`; shear: half).
    pub membrane_stiffness: Option<f64>,
    /// Local damping of the membrane's nodes.
    pub membrane_damping: f64,
    /// Axial strain between measurements, and between frames.
    pub every: f64,
    pub frame_every: f64,
    /// The first `every` of loading is also measured at `every / 2^k` for k from `opening` down
    /// to 1: q rises to about half its peak within the first 0.1 % of strain, and E50 and the
    /// initial Poisson's ratio need that rise resolved (0, as in streams written before the
    /// opening was a setting: none).
    #[serde(default)]
    pub opening: u32,
    /// The axial strain over which the platens come up to speed at the start of loading: their
    /// speed follows `(1 - cos(pi t / T)) / 2` of the full one up to `T = 2 ramp / rate`. A
    /// sudden start (0, as in streams written before the ramp was a setting) sends a stress
    /// wave through the specimen whose peak q can pass the test's own (docs/models/triax.md).
    #[serde(default)]
    pub ramp: f64,
    /// Scale the bodies' inertia for a quasi-static test.
    pub inertia_scaling: bool,
    /// Time step over the critical one.
    pub safety: f64,
    /// Consolidation ends with both platens within this relative tolerance of the pressure and
    /// the unbalanced-force ratio below `unbalanced`.
    pub tolerance: f64,
    pub unbalanced: f64,
    /// Consolidation's balance is judged on blocks of this many steps: the unbalanced-force
    /// ratio of the load-bearing bodies ([`Triax::core_unbalanced`]) averaged over the block,
    /// and the platens at its end.
    #[serde(default = "default_balance_window")]
    pub balance_window: u64,
    /// The particles' local damping during consolidation (`None`: the specimen's own, which
    /// loading keeps).
    #[serde(default)]
    pub consolidation_damping: Option<f64>,
    /// The platens' servo during consolidation: gain and largest strain rate (1/s).
    pub gain: f64,
    pub max_strain_rate: f64,
    /// Steps that consolidation may take.
    pub max_steps: u64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            pressure: 1e5,
            boundary: Boundary::Membrane,
            final_strain: 0.15,
            rate: 0.25,
            young: 7.8e6,
            poisson: 0.5,
            thickness: 2e-3,
            edge: None,
            membrane_stiffness: None,
            membrane_damping: 0.7,
            every: 1e-3,
            frame_every: 5e-3,
            opening: OPENING,
            ramp: RAMP,
            inertia_scaling: true,
            safety: 0.2,
            tolerance: 0.02,
            unbalanced: 5e-3,
            balance_window: BALANCE_WINDOW,
            consolidation_damping: None,
            gain: 0.5,
            max_strain_rate: 4.0,
            max_steps: 2_000_000,
        }
    }
}

/// Why no test.
#[derive(Debug, Error, PartialEq)]
pub enum TriaxError {
    #[error(transparent)]
    TimeStep(#[from] crate::dem::world::TimeStepError),
    /// A parameter out of its range: the [`Params`] field and what it must be.
    #[error("{field} {rule}")]
    Param { field: &'static str, rule: String },
    #[error("the specimen is not a pack specimen in a cylinder (walls: bottom platen, top platen, cylinder): {0}")]
    NotCylinder(String),
    #[error("the state is not a triaxial test's: {0}")]
    NotTriax(String),
    #[error("the membrane: {0}")]
    Membrane(String),
    #[error("not consolidated after {steps} steps: platen stresses {stresses:?} Pa against {target} Pa, unbalanced-force ratio {unbalanced:.3e}")]
    NotConsolidated {
        steps: u64,
        stresses: [f64; 2],
        target: f64,
        unbalanced: f64,
    },
    #[error(
        "a particle left the specimen's boundary at step {step}: body {body} is {distance:.4e} m outside"
    )]
    Escaped {
        step: u64,
        body: usize,
        distance: f64,
    },
}

impl Params {
    /// The platens' speed, as a fraction of the full one, `elapsed` seconds into loading.
    pub fn speed_up(&self, elapsed: f64) -> f64 {
        let duration = 2.0 * self.ramp / self.rate;
        if elapsed >= duration {
            1.0
        } else {
            0.5 * (1.0 - (PI * elapsed / duration).cos())
        }
    }

    /// Checks every parameter.
    pub fn check(&self) -> Result<(), TriaxError> {
        let bad = |field: &'static str, rule: String| Err(TriaxError::Param { field, rule });
        for (field, v) in [
            ("pressure", self.pressure),
            ("rate", self.rate),
            ("young", self.young),
            ("thickness", self.thickness),
            ("every", self.every),
            ("frame_every", self.frame_every),
            ("tolerance", self.tolerance),
            ("unbalanced", self.unbalanced),
            ("max_strain_rate", self.max_strain_rate),
        ] {
            if !(v > 0.0 && v.is_finite()) {
                return bad(field, format!("must be a positive number, got {v}"));
            }
        }
        if self.opening > 30 {
            return bad(
                "opening",
                format!("must be at most 30 halvings, got {}", self.opening),
            );
        }
        if let Some(e) = self.edge {
            if !(e > 0.0 && e.is_finite()) {
                return bad("edge", format!("must be a positive length, got {e}"));
            }
        }
        if !(self.final_strain > 0.0 && self.final_strain < 1.0) {
            return bad(
                "final_strain",
                format!("must be in (0, 1), got {}", self.final_strain),
            );
        }
        if !(self.ramp >= 0.0 && self.ramp.is_finite()) {
            return bad(
                "ramp",
                format!("must be a strain of at least 0, got {}", self.ramp),
            );
        }
        if let Some(k) = self.membrane_stiffness {
            if !(k > 0.0 && k.is_finite()) {
                return bad(
                    "membrane_stiffness",
                    format!("must be a positive stiffness, got {k}"),
                );
            }
        }
        if !(0.0..1.0).contains(&self.membrane_damping) {
            return bad(
                "membrane_damping",
                format!("must be in [0, 1), got {}", self.membrane_damping),
            );
        }
        if !(0.0..=0.5).contains(&self.poisson) {
            return bad(
                "poisson",
                format!("must be in [0, 0.5], got {}", self.poisson),
            );
        }
        for (field, v) in [("safety", self.safety), ("gain", self.gain)] {
            if !(v > 0.0 && v <= 1.0) {
                return bad(field, format!("must be in (0, 1], got {v}"));
            }
        }
        if self.max_steps == 0 {
            return bad("max_steps", "must be at least 1".into());
        }
        if self.balance_window == 0 {
            return bad("balance_window", "must be at least 1 step".into());
        }
        if let Some(d) = self.consolidation_damping {
            if !(0.0..1.0).contains(&d) {
                return bad(
                    "consolidation_damping",
                    format!("must be in [0, 1), got {d}"),
                );
            }
        }
        Ok(())
    }
}

/// The rigid boundary's servo's integral time, steps ([`Triax::servo_cylinder`]): with 30 the
/// cylinder stays within 1.5 % of the pressure through loading of a 36-particle specimen at 2
/// /s (10 is as steady); with 300 it lagged to 119 kPa as the paper Ab_3 test started at 0.5 /s.
const RIGID_INTEGRAL_STEPS: f64 = 30.0;

/// The rigid boundary now: its radius (m), its area (its facet polygon's perimeter times the
/// platens' gap, m^2), its contacts' outward radial push over that area (Pa) and their number.
struct RigidWall {
    radius: f64,
    area: f64,
    stress: f64,
    count: usize,
}

/// The membrane of the test: the facet wall's index among the walls.
pub const MEMBRANE: usize = SIDE;

/// The particles' mean equivalent diameter (m) and their solid volume (m^3).
fn sizes(world: &World) -> (f64, f64) {
    let n = world.bodies.len().max(1) as f64;
    let (mut size, mut solid) = (0.0, 0.0);
    for b in &world.bodies {
        let volume = world.shapes[b.shape as usize].volume;
        size += equivalent_diameter(volume) * b.scale;
        solid += volume * cube(b.scale);
    }
    (size / n, solid)
}

/// Nodes and triangles of a cylindrical membrane about the axis through `point` along `axis`:
/// `segments` nodes on a circle of `radius` (at a cylinder wall's corner angles: the first at
/// the angle of its first corner) on each of `rings + 1` rings from `bottom` to `top`, each
/// quad between two rings cut into two triangles, counter-clockwise seen from the axis.
/// Returns the bottom and top rings' nodes too.
pub fn cylinder_membrane(
    point: &Vec3,
    axis: &Vec3,
    radius: f64,
    segments: usize,
    bottom: f64,
    top: f64,
    rings: usize,
) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<u32>, Vec<u32>) {
    let (e1, e2) = basis(axis);
    let step = 2.0 * PI / segments as f64;
    let height = top - bottom;
    let mut nodes = Vec::with_capacity((rings + 1) * segments);
    for k in 0..=rings {
        let z = if k == rings {
            top
        } else {
            bottom + height * k as f64 / rings as f64
        };
        for j in 0..segments {
            // The cylinder's corner j (see `WallKind::Cylinder`), at this height.
            let a = j as f64 * step;
            let c = point + (e1 * a.cos() + e2 * a.sin()) * radius;
            nodes.push(Vec3::new(c.x, c.y, z));
        }
    }
    let id = |k: usize, j: usize| (k * segments + j % segments) as u32;
    let mut triangles = Vec::with_capacity(2 * rings * segments);
    for k in 0..rings {
        for j in 0..segments {
            for mut t in [
                [id(k, j), id(k, j + 1), id(k + 1, j + 1)],
                [id(k, j), id(k + 1, j + 1), id(k + 1, j)],
            ] {
                // Counter-clockwise seen from the axis: the normal points inwards.
                let [a, b, c] = t.map(|i| nodes[i as usize]);
                let n = (b - a).cross(&(c - a));
                let mid = (a + b + c) / 3.0 - point;
                let out = mid - axis * axis.dot(&mid);
                if n.dot(&out) > 0.0 {
                    t.swap(1, 2);
                }
                triangles.push(t);
            }
        }
    }
    let bottom_ring = (0..segments).map(|j| id(0, j)).collect();
    let top_ring = (0..segments).map(|j| id(rings, j)).collect();
    (nodes, triangles, bottom_ring, top_ring)
}

/// The node mass that makes a node's critical step `dt` against contacts of stiffness `kn` and
/// the membrane's own stiffness at a node `k_membrane`: `(kn + k_membrane) dt^2`.
pub fn node_mass(kn: f64, k_membrane: f64, dt: f64) -> f64 {
    (kn + k_membrane) * dt * dt
}

/// Where the test is, carried in every frame so that a run resumes from it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Progress {
    /// "consolidation" or "loading".
    pub phase: String,
    /// Height and enclosed volume at the start of loading (the strains' references).
    pub height0: f64,
    pub volume0: f64,
    /// Measurements and frames written so far in loading (the next are at these times
    /// `every`, `frame_every`).
    pub measures: u64,
    pub frames: u64,
    /// The step at which the phase started (consolidation's, then loading's).
    pub start_step: u64,
    /// The steps consolidation took (absent in streams written before it was recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub consolidation_steps: Option<u64>,
    /// The specimen's own local damping, which loading restores, while consolidation runs at
    /// [`Params::consolidation_damping`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<f64>,
    /// The rigid boundary's servo's integral term, Pa (absent with a membrane).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lateral_integral: Option<f64>,
    /// The step of a hold's frame ([`Triax::relax`]; absent otherwise): loading that goes on
    /// from it comes up to speed again from there.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub held_at: Option<u64>,
}

impl Progress {
    /// Seconds since the platens last started from rest: the start of loading, or the hold
    /// loading goes on from.
    fn moving_for(&self, w: &World) -> f64 {
        let from = self.held_at.unwrap_or(self.start_step);
        w.step.saturating_sub(from) as f64 * w.dt
    }
}

/// What the test measures, every `every` of axial strain (SI units, compression positive).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measure {
    pub step: u64,
    pub time: f64,
    /// `ln(H0 / H)`.
    pub axial_strain: f64,
    /// `ln(V0 / V)`, `V` the volume the membrane and the platens enclose.
    pub volumetric_strain: f64,
    pub height: f64,
    pub volume: f64,
    /// The platens' mean stress (their normal forces over the end area), Pa.
    pub sigma1: f64,
    /// The confining pressure, Pa.
    pub sigma3: f64,
    /// The bottom and top platens' stresses, Pa.
    pub platens: [f64; 2],
    /// The boundary's `q_g = sigma1 - sigma3`, `p_g = (sigma1 + 2 sigma3) / 3` and their
    /// ratio (Eq. 20).
    pub q_boundary: f64,
    pub p_boundary: f64,
    pub ratio_boundary: f64,
    /// The average stress from the contacts (Eq. 8, wall contacts with their half branch from
    /// the contact point to the body: see [`contact_stress`]) over `volume`, symmetric part:
    /// xx, yy, zz, xy, xz, yz.
    pub stress: [f64; 6],
    /// Its `p`, `q` (Eq. 9) and `q / p`.
    pub p: f64,
    pub q: f64,
    pub ratio: f64,
    /// `p` from the particle pairs alone.
    pub p_pairs: f64,
    /// The lateral boundary's contacts' outward radial force over its area, Pa: on the
    /// membrane, the confining pressure less what its own tension carries; on the rigid
    /// boundary, what its servo holds at the pressure.
    pub membrane_stress: f64,
    /// `q` as a laboratory corrects it: the platens' mean force over the specimen's mean
    /// section `V / H`, less what the lateral boundary transmits (`membrane_stress`), in place of
    /// Eq. 20's end area and cell pressure; on the rigid boundary the section is the cylinder's
    /// (absent in streams written before it was measured: 0).
    #[serde(default)]
    pub q_section: f64,
    /// Particle-particle contacts x 2 over particles, and without rattlers.
    pub coordination: f64,
    pub mechanical_coordination: f64,
    /// The membrane's free nodes' mean and largest distance from the axis, m (the rigid
    /// boundary's radius, both).
    pub radius_mean: f64,
    pub radius_max: f64,
    /// `rate d sqrt(rho / p)`: `d` the mean particle size, `rho` the bodies' mass (scaled,
    /// when it is) over their volume.
    pub inertial: f64,
    /// The largest of the bodies' own inertial numbers, `rate d_b sqrt(rho_b / p)` with each
    /// body's size `d_b` and its own mass (scaled, when it is) over its volume `rho_b`: with
    /// scaled inertia the smallest bodies, heaviest for their size, have the largest (absent
    /// in streams written before it was measured: 0).
    #[serde(default)]
    pub inertial_max: f64,
    pub unbalanced: f64,
    pub contacts: usize,
}

/// A test under way: the world and where the test is.
pub struct Triax {
    pub world: World,
    pub params: Params,
    pub progress: Progress,
    /// The bottom and top rings of the membrane (pinned to the platens).
    rings: [Vec<u32>; 2],
    /// Mean equivalent diameter of the particles, m, and their solid volume, m^3.
    size: f64,
    solid: f64,
}

/// What the test hands its caller as it goes.
pub enum Event<'a> {
    /// Consolidation's progress, every `every_steps`: step, the platens' stresses on the
    /// specimen's section, and the last whole block's unbalanced ratio (infinite before one).
    Consolidating(u64, [f64; 2], f64),
    /// A frame in consolidation, every `checkpoint` steps: the world and the progress to
    /// resume consolidation from.
    Checkpoint(&'a World, &'a Progress),
    Measure(&'a Measure),
    /// A frame: the world and the progress to resume from.
    Frame(&'a World, &'a Progress),
    /// Loading's progress, every [`LOADING_REPORT`] steps: the step and the axial strain.
    Loading(u64, f64),
    /// A hold's progress ([`Triax::relax`]), every [`LOADING_REPORT`] steps: the steps held
    /// and the steps to hold.
    Holding(u64, u64),
}

/// Steps of loading between [`Event::Loading`] reports (cheap: the platens' gap, no
/// measurement).
pub const LOADING_REPORT: u64 = 100;

impl Triax {
    /// The test on a pack specimen: the cylinder swapped for the membrane (or kept, on its
    /// servo, as the rigid boundary), inertia scaled, the time step set. Not yet consolidated.
    pub fn new(mut world: World, params: Params) -> Result<Triax, TriaxError> {
        params.check()?;
        let bounds = container(&world)
            .ok_or_else(|| TriaxError::NotCylinder("its walls are not a pack container".into()))?;
        let Section::Circle { radius, .. } = bounds.section else {
            return Err(TriaxError::NotCylinder("a box".into()));
        };
        let WallKind::Cylinder { point, axis, .. } = world.walls[SIDE].kind else {
            return Err(TriaxError::NotCylinder("wall 2 is not a cylinder".into()));
        };
        if world.bodies.is_empty() {
            return Err(TriaxError::NotCylinder("no particles".into()));
        }
        if params.inertia_scaling {
            scale_inertia(&mut world);
        }
        if params.boundary == Boundary::Rigid {
            return Triax::started(world, params, [Vec::new(), Vec::new()]);
        }
        if world.material.wall_friction > 0.0 {
            return Err(TriaxError::Membrane(format!(
                "its contacts are frictionless, so the specimen's wall_friction must be 0, got {}",
                world.material.wall_friction
            )));
        }
        let sizes: Vec<f64> = (world.bodies.iter())
            .map(|b| equivalent_diameter(world.shapes[b.shape as usize].volume) * b.scale)
            .collect();
        let smallest = sizes.iter().copied().fold(f64::INFINITY, f64::min);
        // Chords no longer than the edge, all outside the cylinder (the nodes on the circle
        // through which the chords pass at the cylinder's radius: no particle overlaps the
        // membrane; the pressure closes the gap, at most `radius (1/cos(pi/n) - cos(pi/s))`);
        // rings at about the edge's spacing.
        let edge = params.edge.unwrap_or(smallest);
        let n = ((2.0 * PI * radius / edge).ceil() as usize).max(12);
        let node_radius = radius / (PI / n as f64).cos();
        let rings = ((bounds.top - bounds.bottom) / edge).ceil().max(2.0) as usize;
        let (nodes, triangles, bottom, top) = cylinder_membrane(
            &point,
            &axis,
            node_radius,
            n,
            bounds.bottom,
            bounds.top,
            rings,
        );
        let pins = (bottom.iter().map(|&node| Pin {
            node,
            wall: BOTTOM as u32,
        }))
        .chain(top.iter().map(|&node| Pin {
            node,
            wall: TOP as u32,
        }))
        .collect();
        // The contacts with the cylinder go with it.
        let kept: Vec<_> = (world.contacts.iter())
            .filter(|(k, _)| k.0 != Partner::Wall(MEMBRANE as u32))
            .map(|(k, c)| (*k, c.clone()))
            .collect();
        world.contacts = Contacts::from_sorted(&kept, false, |x| x.0, |x| x.1.clone());
        let stiffness = params
            .membrane_stiffness
            .unwrap_or(params.young / params.thickness);
        let sheet = Sheet {
            young: params.young,
            poisson: params.poisson,
            thickness: params.thickness,
            pressure: params.pressure,
            node_mass: 1.0,
            kn: stiffness,
            ks: 0.5 * stiffness,
            damping: Some(params.membrane_damping),
            reach: smallest,
        };
        let mut membrane = Membrane::new(
            sheet,
            nodes.clone(),
            &triangles,
            pins,
            true,
            Some(Guide {
                bottom: BOTTOM as u32,
                top: TOP as u32,
            }),
            world.walls.len(),
        )
        .map_err(|e| TriaxError::Membrane(e.to_string()))?;
        let bodies_dt = (world.critical_dts().iter())
            .map(|&(t, r)| t.min(r))
            .fold(f64::INFINITY, f64::min);
        membrane.sheet.node_mass = node_mass(
            sheet.kn.max(sheet.ks) * membrane.contact_area(),
            membrane.node_stiffness(&triangles),
            bodies_dt,
        );
        let mut wall = Wall::facets(nodes, triangles);
        wall.membrane = Some(Box::new(membrane));
        world.walls[MEMBRANE] = wall;
        Triax::started(world, params, [bottom, top])
    }

    /// The test on its walls (inertia scaled already, for the membrane's nodes' mass): the
    /// walls at rest, the time step set, consolidation to come.
    fn started(
        mut world: World,
        params: Params,
        rings: [Vec<u32>; 2],
    ) -> Result<Triax, TriaxError> {
        for w in &mut world.walls {
            w.velocity = Vec3::zeros();
            if let WallKind::Cylinder { radial_rate, .. } = &mut w.kind {
                *radial_rate = 0.0;
            }
        }
        world.dt = world.time_step(params.safety)?;
        let (size, solid) = sizes(&world);
        Ok(Triax {
            size,
            solid,
            rings,
            progress: Progress {
                phase: "consolidation".into(),
                height0: 0.0,
                volume0: 0.0,
                measures: 0,
                frames: 0,
                start_step: world.step,
                consolidation_steps: None,
                damping: None,
                lateral_integral: None,
                held_at: None,
            },
            world,
            params,
        })
    }

    /// A test resumed from one of its frames: the world as written and its progress.
    pub fn resume(world: World, params: Params, progress: Progress) -> Result<Triax, TriaxError> {
        params.check()?;
        let not = |why: &str| TriaxError::NotTriax(why.into());
        if world.bodies.is_empty() {
            return Err(not("no particles"));
        }
        if params.boundary == Boundary::Rigid {
            let Some(WallKind::Cylinder { .. }) = world.walls.get(SIDE).map(|w| &w.kind) else {
                return Err(not(
                    "its settings say a rigid boundary, and wall 2 is not a cylinder",
                ));
            };
            let (size, solid) = sizes(&world);
            return Ok(Triax {
                size,
                solid,
                rings: [Vec::new(), Vec::new()],
                progress,
                world,
                params,
            });
        }
        let (WallKind::Facets { nodes, .. }, Some(m)) = (
            &world
                .walls
                .get(MEMBRANE)
                .ok_or_else(|| not("no membrane wall"))?
                .kind,
            &world.walls[MEMBRANE].membrane,
        ) else {
            return Err(not("wall 2 is not a membrane"));
        };
        let ring = |wall: usize| -> Vec<u32> {
            (m.pins.iter())
                .filter(|p| p.wall as usize == wall)
                .map(|p| p.node)
                .collect()
        };
        let rings = [ring(BOTTOM), ring(TOP)];
        if rings.iter().any(|r| r.len() < 3) || nodes.is_empty() {
            return Err(not("the membrane's ends are not sealed to the platens"));
        }
        let (size, solid) = sizes(&world);
        Ok(Triax {
            size,
            solid,
            rings,
            progress,
            world,
            params,
        })
    }

    /// The platens' z, bottom and top.
    fn platens(&self) -> [f64; 2] {
        let z = |k: usize| match &self.world.walls[k].kind {
            WallKind::Plane { normal, offset } => offset / normal.z,
            _ => f64::NAN,
        };
        [z(BOTTOM), z(TOP)]
    }

    fn nodes(&self) -> &[Vec3] {
        match &self.world.walls[MEMBRANE].kind {
            WallKind::Facets { nodes, .. } => nodes,
            _ => &[],
        }
    }

    /// The rigid boundary's radius and facets (`None`: a membrane).
    fn cylinder(&self) -> Option<(f64, u32)> {
        match (self.params.boundary, &self.world.walls[SIDE].kind) {
            (
                Boundary::Rigid,
                WallKind::Cylinder {
                    radius, segments, ..
                },
            ) => Some((*radius, *segments)),
            _ => None,
        }
    }

    /// The rigid boundary's cross-section, its facet polygon's, and the container it makes
    /// with the platens.
    fn rigid_bounds(&self) -> Option<Bounds> {
        let (radius, segments) = self.cylinder()?;
        let [bottom, top] = self.platens();
        Some(Bounds {
            section: Section::Circle { radius, segments },
            bottom,
            top,
        })
    }

    /// The area of the specimen's end `k` (0 bottom, 1 top): the membrane's ring's polygon seen
    /// along z, or the rigid boundary's section.
    fn end_area(&self, k: usize) -> f64 {
        if let Some(b) = self.rigid_bounds() {
            return b.area();
        }
        let nodes = self.nodes();
        let ring = &self.rings[k];
        let n = ring.len();
        (0..n)
            .map(|i| {
                let (a, b) = (nodes[ring[i] as usize], nodes[ring[(i + 1) % n] as usize]);
                0.5 * (a.x * b.y - b.x * a.y)
            })
            .sum::<f64>()
            .abs()
    }

    /// The volume the membrane and the platens enclose: the membrane's triangles and each end's
    /// ring polygon closed by a fan about its centroid, by the divergence theorem (exact for
    /// the polyhedron they bound).
    pub fn volume(&self) -> f64 {
        if let Some(b) = self.rigid_bounds() {
            return b.area() * b.height();
        }
        let WallKind::Facets {
            nodes, triangles, ..
        } = &self.world.walls[MEMBRANE].kind
        else {
            return f64::NAN;
        };
        let det = |a: &Vec3, b: &Vec3, c: &Vec3| a.dot(&b.cross(c));
        // The membrane's triangles face inwards: minus their terms.
        let mut six = -triangles
            .iter()
            .map(|t| {
                det(
                    &nodes[t[0] as usize],
                    &nodes[t[1] as usize],
                    &nodes[t[2] as usize],
                )
            })
            .sum::<f64>();
        for (k, ring) in self.rings.iter().enumerate() {
            let n = ring.len();
            let centre = ring.iter().map(|&i| nodes[i as usize]).sum::<Vec3>() / n as f64;
            // The rings run counter-clockwise about +z (as built), so the fan faces +z: the
            // bottom's outward normal is -z.
            let sign = if k == 0 { -1.0 } else { 1.0 };
            six += sign
                * (0..n)
                    .map(|i| {
                        let (a, b) = (nodes[ring[i] as usize], nodes[ring[(i + 1) % n] as usize]);
                        det(&centre, &a, &b)
                    })
                    .sum::<f64>();
        }
        six / 6.0
    }

    /// The section the specimen presents to the platens, `V / H`: less than the end rings'
    /// area where the sleeve sags into the voids between the outer particles.
    pub fn section(&self) -> f64 {
        let [zb, zt] = self.platens();
        self.volume() / (zt - zb)
    }

    /// The platens' stresses as consolidation holds them at the pressure, their contact
    /// counts, and the area they are over: the area over which the platens' mean force is the
    /// specimen's own vertical stress, `sigma_zz` of the contacts with their wall halves (Eq.
    /// 8), so that holding them at the cell pressure holds that stress there. Over the end
    /// rings' area (9 % larger than the section `V / H` once the sleeve sags into the voids)
    /// the specimen was loaded axially before the test (q/p 0.16 from the contacts); over
    /// `V / H`, 0.09, as the sleeve's sags also push on the particles along the axis. Before
    /// the platens carry anything, the section.
    fn held_stresses(&self) -> ([f64; 2], [usize; 2], f64) {
        let (over_rings, counts) = self.platen_stresses();
        let forces = [0, 1].map(|k| over_rings[k] * self.end_area(k));
        let mean = 0.5 * (forces[0] + forces[1]);
        let volume = self.volume();
        let (full, _) = contact_stress(&self.world, volume);
        let vertical = full[(2, 2)];
        let area = if mean > 0.0 && vertical > 0.0 {
            mean / vertical
        } else {
            self.section()
        };
        (forces.map(|f| f / area), counts, area)
    }

    /// The platens' stresses (their normal force over the end area) and contact counts.
    fn platen_stresses(&self) -> ([f64; 2], [usize; 2]) {
        let mut counts = [0usize; 2];
        let first = self.world.contacts.lower_bound(&(Partner::Wall(0), 0));
        for (&(partner, _), _) in self.world.contacts.iter().skip(first) {
            if let Partner::Wall(k) = partner {
                if let Some(n) = counts.get_mut(k as usize) {
                    *n += 1;
                }
            }
        }
        let stress = |k: usize| {
            let w = &self.world.walls[k];
            match &w.kind {
                WallKind::Plane { normal, .. } => -w.force.dot(normal) / self.end_area(k),
                _ => f64::NAN,
            }
        };
        ([stress(BOTTOM), stress(TOP)], counts)
    }

    /// Measures the specimen as it is now.
    pub fn measure(&self) -> Measure {
        let w = &self.world;
        let [zb, zt] = self.platens();
        let height = zt - zb;
        let volume = self.volume();
        let (platens, _) = self.platen_stresses();
        let sigma1 = 0.5 * (platens[0] + platens[1]);
        let force = 0.5 * (platens[0] * self.end_area(BOTTOM) + platens[1] * self.end_area(TOP));
        let sigma3 = self.params.pressure;
        let (full, pairs) = contact_stress(w, volume);
        let (p, q) = invariants(&full);
        let (p_pairs, _) = invariants(&pairs);
        let (coordination, mechanical_coordination) = coordination(w);
        // The lateral boundary: its contacts' outward radial push over its area, and its radius.
        let (push, _) = self.lateral_push();
        let (mut area, mut radii) = (0.0, Vec::new());
        if let Some(r) = self.rigid_wall() {
            (area, radii) = (r.area, vec![r.radius]);
        } else if let WallKind::Facets {
            nodes, triangles, ..
        } = &w.walls[MEMBRANE].kind
        {
            area = (triangles.iter())
                .map(|t| {
                    let [a, b, c] = t.map(|i| nodes[i as usize]);
                    0.5 * (b - a).cross(&(c - a)).norm()
                })
                .sum();
            let m = w.walls[MEMBRANE].membrane.as_deref();
            radii = (nodes.iter().enumerate())
                .filter(|(i, _)| m.is_some_and(|m| m.pin_of(*i).is_none()))
                .map(|(_, x)| x.xy().norm())
                .collect();
        }
        let membrane_stress = if area > 0.0 { push / area } else { 0.0 };
        let mass: f64 = w.bodies.iter().map(|b| b.mass).sum();
        let density = mass / self.solid;
        let strain = |a: f64, b: f64| if b > 0.0 { (b / a).ln() } else { 0.0 };
        let radius_mean = radii.iter().sum::<f64>() / radii.len().max(1) as f64;
        let radius_max = radii.iter().copied().fold(0.0, f64::max);
        Measure {
            step: w.step,
            time: w.time,
            axial_strain: strain(height, self.progress.height0),
            volumetric_strain: strain(volume, self.progress.volume0),
            height,
            volume,
            sigma1,
            sigma3,
            platens,
            q_boundary: sigma1 - sigma3,
            p_boundary: (sigma1 + 2.0 * sigma3) / 3.0,
            ratio_boundary: 3.0 * (sigma1 - sigma3) / (sigma1 + 2.0 * sigma3),
            stress: symmetric_components(&full),
            p,
            q,
            ratio: if p != 0.0 { q / p } else { 0.0 },
            p_pairs,
            membrane_stress,
            q_section: force * height / volume - membrane_stress,
            coordination,
            mechanical_coordination,
            radius_mean,
            radius_max,
            inertial: self.params.rate * self.size * (density / self.params.pressure).sqrt(),
            inertial_max: self.largest_inertial(),
            unbalanced: w.unbalanced,
            contacts: w.contacts.len(),
        }
    }

    /// The largest of the bodies' own inertial numbers ([`Measure::inertial_max`]).
    fn largest_inertial(&self) -> f64 {
        let w = &self.world;
        (w.bodies.iter())
            .map(|b| {
                let volume = w.shapes[b.shape as usize].volume;
                let density = b.mass / (volume * cube(b.scale));
                let size = equivalent_diameter(volume) * b.scale;
                self.params.rate * size * (density / self.params.pressure).sqrt()
            })
            .fold(0.0, f64::max)
    }

    /// The lateral boundary's contacts' outward radial force (N) and their number.
    fn lateral_push(&self) -> (f64, usize) {
        let w = &self.world;
        let (mut push, mut count) = (0.0, 0);
        let first = w.contacts.lower_bound(&(Partner::Wall(SIDE as u32), 0));
        for (&(partner, _), c) in w.contacts.iter().skip(first) {
            if partner != Partner::Wall(SIDE as u32) {
                break;
            }
            let out = Vec3::new(c.point.x, c.point.y, 0.0);
            let len = out.norm();
            if len > 0.0 {
                push += (c.normal * c.normal_force + c.shear).dot(&out) * -1.0 / len;
            }
            count += 1;
        }
        (push, count)
    }

    /// The rigid boundary as its servo and the measurements see it; `None` with a membrane.
    fn rigid_wall(&self) -> Option<RigidWall> {
        let b = self.rigid_bounds()?;
        let (push, count) = self.lateral_push();
        let area = b.perimeter() * b.height();
        let Section::Circle { radius, .. } = b.section else {
            return None;
        };
        Some(RigidWall {
            radius,
            area,
            stress: push / area,
            count,
        })
    }

    /// Stops the walls: the platens and the rigid boundary's radius.
    fn stop_walls(&mut self) {
        set_speeds(&mut self.world, &[0.0, 0.0]);
        if let WallKind::Cylinder { radial_rate, .. } = &mut self.world.walls[SIDE].kind {
            *radial_rate = 0.0;
        }
    }

    /// The rigid boundary's servo for this step: PFC's for a wall (its stress the outward
    /// push over its area) with integral action, so that a specimen dilating at a steady rate
    /// is followed without a steady error (PFC's proportional law alone lags by the error that
    /// makes the speed: 12 % of the pressure on a 36-particle specimen at 2 /s). The speed
    /// inward is `g (e + I)`, `g` the wall's gain ([`wall_gain`]), `e` the pressure less the
    /// stress, and `I` grows by `e / RIGID_INTEGRAL_STEPS` each step while the speed is below
    /// its cap; it is set as the radius's rate. Nothing with a membrane.
    fn servo_cylinder(&mut self, law: &ServoLaw) {
        let Some(RigidWall {
            radius,
            area,
            stress,
            count,
        }) = self.rigid_wall()
        else {
            return;
        };
        let geometry = WallGeometry {
            area,
            half: radius,
            weight: 1.0,
        };
        let g = wall_gain(&self.world, law, &geometry, count);
        let cap = law.max_strain_rate * radius;
        let error = law.pressure - stress;
        let integral = self.progress.lateral_integral.get_or_insert(0.0);
        let wanted = g * (error + *integral);
        if wanted.abs() < cap {
            *integral += error / RIGID_INTEGRAL_STEPS;
        }
        if let WallKind::Cylinder { radial_rate, .. } = &mut self.world.walls[SIDE].kind {
            *radial_rate = -wanted.clamp(-cap, cap);
        }
    }

    /// The platens' servo law: PFC's, to the pressure, each platen on its own, without a rest
    /// band (a platen that rested within the tolerance and started again at its edge sent a
    /// jolt through the specimen each time: the unbalanced ratio rose tenfold).
    fn platen_law(&self) -> ServoLaw {
        let p = &self.params;
        ServoLaw {
            pressure: p.pressure,
            gain: p.gain,
            max_strain_rate: p.max_strain_rate,
            loose_strain_rate: p.max_strain_rate,
            integral_steps: 0,
            tolerance: 0.0,
        }
    }

    /// One step with the platens following their servo to the pressure, their stresses as
    /// [`Triax::held_stresses`] has them.
    fn servo_step(&mut self, law: &ServoLaw) {
        let (stresses, counts, area) = self.held_stresses();
        let [zb, zt] = self.platens();
        let half = 0.5 * (zt - zb);
        let geometry: Vec<WallGeometry> = (0..2)
            .map(|_| WallGeometry {
                area,
                half,
                weight: 0.5,
            })
            .collect();
        let speeds = servo(&self.world, law, &geometry, &stresses, &counts, None);
        set_speeds(&mut self.world, &speeds);
        self.servo_cylinder(law);
        self.world.step();
    }

    /// Step 2: the platens servo to the pressure on the specimen's section while the membrane
    /// holds it, until the specimen is in equilibrium; the platens then stop. Balance is
    /// judged on blocks of [`Params::balance_window`] steps: at a block's end, both platens
    /// within the tolerance and the block's mean of [`Triax::core_unbalanced`] below
    /// `unbalanced`. The particles' damping is [`Params::consolidation_damping`] meanwhile.
    /// `report` sees the progress every `every_steps`, and a frame to resume from every
    /// `checkpoint` steps of consolidation (0: none; at a block's end, where nothing of the
    /// block is carried over). A test resumed from such a frame goes on from it: steps count
    /// from consolidation's start, and the bytes are those of the run in one go.
    pub fn consolidate(
        &mut self,
        every_steps: u64,
        checkpoint: u64,
        report: &mut (impl FnMut(Event) + Send),
    ) -> Result<(), TriaxError> {
        if self.progress.phase != "consolidation" {
            return Err(TriaxError::NotTriax(format!(
                "consolidation asked of a test in phase '{}'",
                self.progress.phase
            )));
        }
        if checkpoint % self.params.balance_window != 0 {
            return Err(TriaxError::Param {
                field: "checkpoint_every",
                rule: format!(
                    "must be a multiple of the balance window, {} steps, got {checkpoint}",
                    self.params.balance_window
                ),
            });
        }
        if let Some(d) = self.params.consolidation_damping {
            self.progress
                .damping
                .get_or_insert(self.world.material.damping);
            self.world.material.damping = d;
        }
        let law = self.platen_law();
        let window = self.params.balance_window;
        let (start, resumed_at) = (self.progress.start_step, self.world.step);
        // The block's sum so far, and the last whole block's mean (unknown at first).
        let (mut block, mut ratio) = (0.0, f64::INFINITY);
        let outcome = on_pool(|| loop {
            let steps = self.world.step - start;
            let (stresses, _, _) = self.held_stresses();
            let at_end = steps > 0 && steps % window == 0;
            if at_end && self.world.step > resumed_at {
                ratio = block / window as f64;
                block = 0.0;
            }
            if steps > 0 && steps % every_steps == 0 {
                report(Event::Consolidating(steps, stresses, ratio));
            }
            let near = |s: &f64| {
                (s - self.params.pressure).abs() <= self.params.tolerance * self.params.pressure
            };
            // A resumed run starts at a block's end with no block behind it: it does not end.
            let lateral = self.rigid_wall().map(|r| r.stress);
            if at_end
                && self.world.step > resumed_at
                && stresses.iter().all(near)
                && lateral.as_ref().is_none_or(near)
                && ratio < self.params.unbalanced
            {
                return Ok(());
            }
            if steps >= self.params.max_steps {
                return Err(TriaxError::NotConsolidated {
                    steps,
                    stresses,
                    target: self.params.pressure,
                    unbalanced: ratio,
                });
            }
            if checkpoint > 0 && steps % checkpoint == 0 && self.world.step > resumed_at {
                report(Event::Checkpoint(&self.world, &self.progress));
            }
            self.servo_step(&law);
            block += self.core_unbalanced();
        });
        self.stop_walls();
        outcome?;
        if let Some(d) = self.progress.damping {
            self.world.material.damping = d;
        }
        let [zb, zt] = self.platens();
        self.progress = Progress {
            phase: "loading".into(),
            height0: zt - zb,
            volume0: self.volume(),
            measures: 0,
            frames: 0,
            start_step: self.world.step,
            consolidation_steps: Some(self.world.step - start),
            damping: None,
            lateral_integral: self.progress.lateral_integral,
            held_at: None,
        };
        Ok(())
    }

    /// The unbalanced-force ratio of the load-bearing bodies: the mean magnitude of the net
    /// contact force (and gravity) on the bodies with two contacts or more, over the mean
    /// force of the particle pairs' contacts. Rattlers (no contact or one), which damping
    /// does not hold still, and the membrane's many light contacts, which would dilute the
    /// mean contact force, are left out; infinite with no particle pair.
    pub fn core_unbalanced(&self) -> f64 {
        let w = &self.world;
        let mut net: Vec<(Vec3, u32)> =
            (w.bodies.iter()).map(|b| (w.gravity * b.mass, 0)).collect();
        let (mut pair_force, mut pairs) = (0.0, 0usize);
        for (&(partner, b), c) in &w.contacts {
            let f = c.normal * c.normal_force + c.shear;
            net[b as usize].0 += f;
            net[b as usize].1 += 1;
            if let Partner::Body(a) = partner {
                net[a as usize].0 -= f;
                net[a as usize].1 += 1;
                pair_force += f.norm();
                pairs += 1;
            }
        }
        let (mut sum, mut bearing) = (0.0, 0usize);
        for (f, n) in &net {
            if *n >= 2 {
                sum += f.norm();
                bearing += 1;
            }
        }
        if pairs == 0 || bearing == 0 || !(pair_force > 0.0) {
            return f64::INFINITY;
        }
        (sum / bearing as f64) / (pair_force / pairs as f64)
    }

    /// `steps` steps of the consolidation's hold: the platens on their servo to the pressure,
    /// the membrane at it, no loading (the hydrostatic hold's test).
    pub fn hold(&mut self, steps: u64) {
        let law = self.platen_law();
        on_pool(|| (0..steps).for_each(|_| self.servo_step(&law)));
        self.stop_walls();
    }

    /// Step 3: loading from where the progress is to `final_strain` (or `stop_at`, if lower:
    /// the run then ends with a frame there, from which it resumes), with the measurements and
    /// frames handed to `sink` as they come. Every particle is checked to be inside the
    /// membrane at each measurement.
    pub fn load(
        &mut self,
        stop_at: Option<f64>,
        sink: &mut (impl FnMut(Event) + Send),
    ) -> Result<(), TriaxError> {
        let end = stop_at.map_or(self.params.final_strain, |s| {
            s.min(self.params.final_strain)
        });
        let frame_every = self.params.frame_every;
        let schedule = Schedule::of(&self.params);
        let law = self.platen_law();
        on_pool(|| loop {
            let [zb, zt] = self.platens();
            let strain = (self.progress.height0 / (zt - zb)).ln();
            let finished = strain >= end;
            let measure_due = strain >= schedule.due(self.progress.measures);
            let frame_due = strain >= self.progress.frames as f64 * frame_every;
            if measure_due || finished {
                let m = self.measure();
                self.check_contained()?;
                if measure_due {
                    self.progress.measures = schedule.next_after(strain);
                }
                sink(Event::Measure(&m));
            }
            if frame_due || finished {
                if frame_due {
                    self.progress.frames = (strain / frame_every).floor() as u64 + 1;
                }
                sink(Event::Frame(&self.world, &self.progress));
            }
            if finished {
                return Ok(());
            }
            if self.world.step % LOADING_REPORT == 0 {
                sink(Event::Loading(self.world.step, strain));
            }
            self.drive_platens(self.params.speed_up(self.progress.moving_for(&self.world)));
            self.servo_cylinder(&law);
            self.world.step();
        })
    }

    /// The platens approaching each other at `fraction` of the loading speed, the rate times
    /// the specimen's height, each at half of it.
    fn drive_platens(&mut self, fraction: f64) {
        let [zb, zt] = self.platens();
        let v = self.params.rate * (zt - zb) * fraction;
        self.world.walls[BOTTOM].velocity = Vec3::z() * (0.5 * v);
        self.world.walls[TOP].velocity = -Vec3::z() * (0.5 * v);
    }

    /// A hold from where the test is, `steps` steps in all: the platens slow down from
    /// loading's speed as they came up to it (over `ramp` of strain, [`Params::speed_up`]
    /// backwards; a stop at once sends an unloading wave through the specimen) and then stay
    /// still, while the lateral boundary stays at the pressure (the membrane's, or the rigid
    /// boundary on its servo), so that the specimen relaxes with nothing driven. A
    /// measurement and a frame go to `sink` every `every` steps and at the end; the progress
    /// passes by the measurements and frames the slowing down went by and records
    /// [`Progress::held_at`], so that loading goes on from the held state, coming up to speed
    /// again from rest.
    pub fn relax(
        &mut self,
        steps: u64,
        every: u64,
        sink: &mut (impl FnMut(Event) + Send),
    ) -> Result<(), TriaxError> {
        let law = self.platen_law();
        let every = every.max(1);
        let dt = self.world.dt;
        let speed = if self.progress.phase == "loading" {
            self.params.speed_up(self.progress.moving_for(&self.world))
        } else {
            0.0
        };
        let schedule = Schedule::of(&self.params);
        let frame_every = self.params.frame_every;
        let slowing = 2.0 * self.params.ramp / self.params.rate;
        on_pool(|| {
            for held in 1..=steps {
                let t = (held - 1) as f64 * dt;
                let f = if t < slowing {
                    speed * 0.5 * (1.0 + (PI * t / slowing).cos())
                } else {
                    0.0
                };
                self.drive_platens(f);
                self.servo_cylinder(&law);
                self.world.step();
                if held % every == 0 || held == steps {
                    let m = self.measure();
                    self.check_contained()?;
                    // Loading's measurements and frames due in the slowing down are passed
                    // by, and loading goes on from rest.
                    let strain = m.axial_strain;
                    if strain >= schedule.due(self.progress.measures) {
                        self.progress.measures = schedule.next_after(strain);
                    }
                    if strain >= self.progress.frames as f64 * frame_every {
                        self.progress.frames = (strain / frame_every).floor() as u64 + 1;
                    }
                    self.progress.held_at = Some(self.world.step);
                    sink(Event::Measure(&m));
                    sink(Event::Frame(&self.world, &self.progress));
                }
                if held % LOADING_REPORT == 0 {
                    sink(Event::Holding(held, steps));
                }
            }
            Ok(())
        })
    }

    /// Every particle's centroid within the membrane's farthest free node from the axis (or the
    /// rigid boundary's radius) and between the platens.
    fn check_contained(&self) -> Result<(), TriaxError> {
        let nodes = self.nodes();
        let m = self.world.walls[MEMBRANE].membrane.as_deref();
        let outer = match self.cylinder() {
            Some((radius, _)) => radius,
            None => (nodes.iter().enumerate())
                .filter(|(i, _)| m.is_some_and(|m| m.pin_of(*i).is_none()))
                .map(|(_, x)| x.xy().norm())
                .fold(0.0, f64::max),
        };
        let [zb, zt] = self.platens();
        for (i, b) in self.world.bodies.iter().enumerate() {
            let out = (b.pos.xy().norm() - outer)
                .max(zb - b.pos.z)
                .max(b.pos.z - zt);
            if out > 0.0 {
                return Err(TriaxError::Escaped {
                    step: self.world.step,
                    body: i,
                    distance: out,
                });
            }
        }
        Ok(())
    }
}

/// The test's macroscopic results (digest section 5), from its measurements in loading.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Summary {
    /// The largest `q_boundary`, Pa, and the axial strain where it is.
    pub peak_q: f64,
    pub peak_strain: f64,
    /// Secant modulus at half the peak: `(peak_q / 2) / eps_50`, Pa.
    pub e50: f64,
    /// `eps_50`, the axial strain where q first reaches half the peak (interpolated between
    /// measurements): an E50 read within the first 0.1 % depends on the loading rate
    /// (docs/models/triax.md, the start of loading).
    pub e50_strain: f64,
    /// `(1 - d eps_v / d eps_a) / 2`, the slope fitted (least squares) over the measurements
    /// up to `eps_50`.
    pub poisson_ratio: f64,
    /// Peak friction angle, degrees: `sin phi = (s1 - s3) / (s1 + s3)` at the peak.
    pub friction_angle: f64,
    /// The largest [`Measure::q_section`], Pa, the axial strain where it is, and the friction
    /// angle from it, `s3` the lateral boundary's stress.
    pub peak_q_section: f64,
    pub peak_strain_section: f64,
    pub friction_angle_section: f64,
    /// Dilatancy angle, degrees: `sin psi = -(d eps_v / d eps_a) / (2 - d eps_v / d eps_a)` at
    /// the largest dilation rate (the slope fitted over `window` measurements either side).
    pub dilatancy_angle: f64,
    /// The axial strain of the largest dilation rate.
    pub dilatancy_strain: f64,
    pub final_axial_strain: f64,
    pub final_volumetric_strain: f64,
    pub measures: usize,
}

/// When loading's measurements are due: measurement 0 at strain 0, then the `opening` ones at
/// `every / 2^k` (k from `opening` down to 1), then every `every`.
#[derive(Clone, Copy, Debug)]
pub struct Schedule {
    pub every: f64,
    pub opening: u32,
}

impl Schedule {
    pub fn of(params: &Params) -> Schedule {
        Schedule {
            every: params.every,
            opening: params.opening,
        }
    }

    /// The strain at which measurement `m` is due.
    pub fn due(&self, m: u64) -> f64 {
        let k = u64::from(self.opening);
        match m {
            0 => 0.0,
            m if m <= k => self.every / (1u64 << (k + 1 - m)) as f64,
            m => (m - k) as f64 * self.every,
        }
    }

    /// The first measurement due after `strain` (one measured at `strain` covers every
    /// measurement due at or before it).
    pub fn next_after(&self, strain: f64) -> u64 {
        let k = u64::from(self.opening);
        let regular = (strain / self.every).floor() as u64 + 1 + k;
        if strain >= self.every {
            regular
        } else {
            (1..=k).find(|&m| self.due(m) > strain).unwrap_or(k + 1)
        }
    }

    /// The due strain nearest `strain`: the one a measurement there was taken for (a step
    /// past it), or the next one for the last measurement a hair short of it.
    pub fn nominal(&self, strain: f64) -> f64 {
        let m = self.next_after(strain);
        let (before, after) = (self.due(m.saturating_sub(1)), self.due(m));
        if after - strain < strain - before {
            after
        } else {
            before
        }
    }
}

/// Measurements either side of a point over which the dilation rate is fitted.
pub const DILATANCY_WINDOW: usize = 5;

/// The least-squares slope of `y` against `x`; `None` for fewer than two distinct `x`.
fn slope(points: &[(f64, f64)]) -> Option<f64> {
    let n = points.len() as f64;
    let (mx, my) = points
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx))
    });
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The summary of a test's measurements in loading (in strain order; a hold's, which do not
/// advance the strain, are left out); `None` with fewer than
/// three or no positive peak.
pub fn summarize(series: &[Measure]) -> Option<Summary> {
    // A hold's measurements ([`Triax::relax`]) repeat the strain: loading's are the ones
    // that advance it.
    let mut reach = f64::NEG_INFINITY;
    let loading: Vec<Measure> = (series.iter())
        .filter(|m| {
            let on = m.axial_strain > reach;
            reach = reach.max(m.axial_strain);
            on
        })
        .cloned()
        .collect();
    let series = &loading[..];
    if series.len() < 3 {
        return None;
    }
    let peak = series
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.q_boundary.total_cmp(&b.1.q_boundary))?
        .0;
    let top = &series[peak];
    if !(top.q_boundary > 0.0) {
        return None;
    }
    let half = 0.5 * top.q_boundary;
    let k = series.iter().position(|m| m.q_boundary >= half)?;
    let eps50 = if k == 0 {
        series[0].axial_strain
    } else {
        let (a, b) = (&series[k - 1], &series[k]);
        let f = (half - a.q_boundary) / (b.q_boundary - a.q_boundary);
        a.axial_strain + f * (b.axial_strain - a.axial_strain)
    };
    let initial: Vec<(f64, f64)> = (series.iter())
        .take_while(|m| m.axial_strain <= eps50)
        .map(|m| (m.axial_strain, m.volumetric_strain))
        .collect();
    let initial = if initial.len() >= 3 {
        initial
    } else {
        (series.iter().take(3))
            .map(|m| (m.axial_strain, m.volumetric_strain))
            .collect()
    };
    let nu = (1.0 - slope(&initial)?) / 2.0;
    let points: Vec<(f64, f64)> = (series.iter())
        .map(|m| (m.axial_strain, m.volumetric_strain))
        .collect();
    let w = DILATANCY_WINDOW;
    let (mut rate, mut at) = (f64::INFINITY, 0.0);
    for i in 0..points.len() {
        let window = &points[i.saturating_sub(w)..(i + w + 1).min(points.len())];
        if let Some(s) = slope(window) {
            if s < rate {
                (rate, at) = (s, points[i].0);
            }
        }
    }
    let degrees = |sin: f64| sin.clamp(-1.0, 1.0).asin().to_degrees();
    let last = series.last()?;
    let section = (series.iter())
        .max_by(|a, b| a.q_section.total_cmp(&b.q_section))
        .filter(|m| m.q_section > 0.0);
    let (peak_q_section, peak_strain_section, friction_angle_section) = match section {
        Some(m) => {
            let s3 = m.membrane_stress;
            let angle = degrees(m.q_section / (m.q_section + 2.0 * s3));
            (m.q_section, m.axial_strain, angle)
        }
        None => (f64::NAN, f64::NAN, f64::NAN),
    };
    Some(Summary {
        peak_q: top.q_boundary,
        peak_strain: top.axial_strain,
        e50: if eps50 > 0.0 { half / eps50 } else { f64::NAN },
        e50_strain: eps50,
        poisson_ratio: nu,
        friction_angle: degrees((top.sigma1 - top.sigma3) / (top.sigma1 + top.sigma3)),
        peak_q_section,
        peak_strain_section,
        friction_angle_section,
        dilatancy_angle: degrees(-rate / (2.0 - rate)),
        dilatancy_strain: at,
        final_axial_strain: last.axial_strain,
        final_volumetric_strain: last.volumetric_strain,
        measures: series.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The summary of a series built to known answers: q rises at 100 MPa to 200 kPa at 0.2 %
    /// and on to 300 kPa at 15 %, so half the peak lies between two measurements (0.15 %);
    /// eps_v rises at 0.2 eps_a (nu 0.4) to 1 % and then falls at 0.5 (sin psi = 0.2).
    #[test]
    fn the_summary_reads_a_known_series() {
        let series: Vec<Measure> = (0..=150)
            .map(|k| {
                let e = k as f64 * 1e-3;
                let q = if e <= 2e-3 {
                    1e8 * e
                } else {
                    2e5 + (e - 2e-3) * 1e5 / 0.148
                };
                let ev = if e <= 0.01 {
                    0.2 * e
                } else {
                    2e-3 - 0.5 * (e - 0.01)
                };
                Measure {
                    axial_strain: e,
                    volumetric_strain: ev,
                    sigma1: 1e5 + q,
                    sigma3: 1e5,
                    q_boundary: q,
                    ..Measure::default()
                }
            })
            .collect();
        let s = summarize(&series).unwrap();
        assert!((s.peak_q - 3e5).abs() < 1e-6, "{s:?}");
        assert!((s.peak_strain - 0.15).abs() < 1e-12);
        assert!((s.e50_strain - 1.5e-3).abs() < 1e-12, "{}", s.e50_strain);
        assert!((s.e50 - 1e8).abs() < 1e-3, "{}", s.e50);
        assert!((s.poisson_ratio - 0.4).abs() < 1e-9, "{}", s.poisson_ratio);
        assert!((s.friction_angle - 0.6f64.asin().to_degrees()).abs() < 1e-9);
        assert!((s.dilatancy_angle - 0.2f64.asin().to_degrees()).abs() < 1e-9);
        assert!(s.dilatancy_strain > 0.015, "{}", s.dilatancy_strain);
        assert!((s.final_volumetric_strain - (2e-3 - 0.5 * 0.14)).abs() < 1e-12);
    }

    /// The platens start from rest and reach full speed, smoothly and monotonically, at the
    /// strain `ramp` (at the full rate from the start the same strain would take half the
    /// time); without a ramp, as in streams written before it was a setting, at once.
    #[test]
    fn the_platens_come_up_to_speed_over_the_ramp() {
        let p = Params {
            rate: 0.5,
            ramp: 5e-4,
            ..Params::default()
        };
        let duration = 2.0 * p.ramp / p.rate;
        assert_eq!(p.speed_up(0.0), 0.0);
        assert!((p.speed_up(0.5 * duration) - 0.5).abs() < 1e-12);
        assert_eq!(p.speed_up(duration), 1.0);
        assert_eq!(p.speed_up(10.0 * duration), 1.0);
        let n = 100_000;
        let dt = duration / n as f64;
        let speeds: Vec<f64> = (0..=n).map(|i| p.speed_up(i as f64 * dt)).collect();
        assert!(speeds.windows(2).all(|w| w[1] >= w[0]));
        let strain: f64 = speeds
            .windows(2)
            .map(|w| 0.5 * (w[0] + w[1]) * p.rate * dt)
            .sum();
        assert!(
            (strain - p.ramp).abs() < 1e-9 * p.ramp,
            "strain over the ramp {strain}"
        );
        let sudden = Params {
            ramp: 0.0,
            ..p.clone()
        };
        assert_eq!(sudden.speed_up(0.0), 1.0);
        let old: Params = serde_json::from_value(serde_json::json!({
            "pressure": 1e5, "final_strain": 0.15, "rate": 0.5, "young": 7.8e6, "poisson": 0.5,
            "thickness": 0.002, "edge": null, "membrane_stiffness": null,
            "membrane_damping": 0.7, "every": 0.001, "frame_every": 0.005,
            "inertia_scaling": true, "safety": 0.2, "tolerance": 0.02, "unbalanced": 0.001,
            "gain": 0.5, "max_strain_rate": 4.0, "max_steps": 2000000
        }))
        .unwrap();
        assert_eq!((old.ramp, old.opening), (0.0, 0));
        for bad in [-1e-4, f64::INFINITY, f64::NAN] {
            let e = Params {
                ramp: bad,
                ..p.clone()
            }
            .check()
            .unwrap_err();
            assert!(e.to_string().starts_with("ramp must be"), "{e}");
        }
    }

    /// Without an opening the measurements are due every `every`, as in streams written before
    /// the opening was a setting; with one, the first `every` is halved `opening` times, and a
    /// measurement taken a step past a due strain is due next at the following one.
    #[test]
    fn the_schedule_halves_the_first_interval_and_keeps_the_rest() {
        let plain = Schedule {
            every: 1e-3,
            opening: 0,
        };
        for m in 0..300u64 {
            assert_eq!(plain.due(m), m as f64 * 1e-3);
            let past = plain.due(m) + 1e-6;
            assert_eq!(plain.next_after(past), (past / 1e-3).floor() as u64 + 1);
            assert_eq!(plain.nominal(past), plain.due(m));
        }
        let fine = Schedule {
            every: 1e-3,
            opening: 5,
        };
        let dues: Vec<f64> = (0..9).map(|m| fine.due(m)).collect();
        let want = [
            0.0,
            1e-3 / 32.0,
            1e-3 / 16.0,
            1e-3 / 8.0,
            1e-3 / 4.0,
            5e-4,
            1e-3,
            2e-3,
            3e-3,
        ];
        for (d, w) in dues.iter().zip(want) {
            assert!((d - w).abs() < 1e-18, "{dues:?}");
        }
        for m in 0..200u64 {
            let past = fine.due(m) + 1e-7;
            assert_eq!(fine.next_after(past), m + 1, "after measurement {m}");
            assert_eq!(fine.nominal(past), fine.due(m));
        }
        // A step that crosses two due strains takes one measurement for both.
        assert_eq!(fine.next_after(0.3e-3), 5);
        // The last measurement a hair short of its due strain is named after it.
        assert_eq!(fine.nominal(0.15 - 1e-12), fine.due(155));
    }
}
