//! Dense, isotropically consolidated specimens of polyhedra (the `pack` tool).
//!
//! The preparation, step by step (docs/models/pack.md tells why each choice):
//! 1. **Sizes.** Particle `i` is template `i mod T`, its size drawn uniformly between
//!    `size_min` and `size_max` ([`SizeMeasure`]: equivalent-sphere diameter by default). Unless
//!    a count is given, particles are drawn until their solid volume fills the container at
//!    `porosity`, rounded up to a multiple of `T` (equal numbers of each template).
//! 2. **Cloud.** The container is scaled up by one factor in all directions until the particles
//!    fill `cloud_fraction` of it, and they are placed there at random, largest first, each
//!    with a uniformly random orientation, wherever it is inside and clear of the others (an
//!    exact separation test). Nothing touches.
//! 3. **Compaction.** No gravity (a 600 mm column of sand under gravity would vary its stress by
//!    a tenth of the 100 kPa target). The two platens and the cylinder wall (or the box's four
//!    sides), all frictionless, move in at one strain rate, so the cloud shrinks alike in every
//!    direction (an isotropic fabric): the rate follows the mean wall stress under PFC's servo
//!    law with integral action (see [`servo`]),
//!    capped at `max_strain_rate` (`loose_strain_rate` while there are fewer particle-particle
//!    contacts than particles). Particle friction is the preparation friction, damping
//!    `prep_damping`. It ends when the mean stress is within `tolerance` of `p` and either the
//!    unbalanced-force ratio is below `prep_unbalanced` or the porosity has changed by less than
//!    1e-4 over the last 10 000 steps (frictionless packings keep sliding at the target).
//! 4. **Equilibrium.** The particle friction becomes the material's (the damping stays
//!    `prep_damping`, by default the material's 0.3), and each wall
//!    follows its own servo (resting while within half the tolerance) until every wall stress
//!    is within `tolerance` of `p` and the unbalanced-force ratio is below `unbalanced`. The
//!    walls then stop, the true inertia comes back, every body is set at rest, and the state
//!    is the specimen.
//!
//! Steps 3 and 4 run with density scaling ([`scale_inertia`]) unless `inertia_scaling` is off.

use super::boundary::{
    bounds, core_porosity, mean_stress, porosity, porosity_of, solid_volume, stresses_in,
    wall_stresses, Bounds, Section,
};
use super::inertia::{restore_inertia, scale_inertia};
use super::servo::{servo, set_speeds, ServoLaw};
use crate::dem::collision::gjk;
use crate::dem::contacts::Partner;
use crate::dem::law::Material;
use crate::dem::shape::Shape;
use crate::dem::world::World;
use crate::geometry::mass::equivalent_diameter;
use crate::math::{cube, random_rotation, square, Vec3};
use crate::micro::fabric::anisotropy;
use crate::micro::stress::coordination;
use nalgebra::UnitQuaternion;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::HashMap;
use std::f64::consts::PI;
use thiserror::Error;

/// The container's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Container {
    /// A cylinder about the z axis (the prism of `segments` facets) between two platens: walls
    /// bottom, top, cylinder.
    Cylinder,
    /// A box of four side planes between two platens: walls bottom, top, x-min, x-max, y-min,
    /// y-max.
    Box,
}

/// What a particle's size is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SizeMeasure {
    /// The diameter of the sphere of the same volume (the default).
    Equivalent,
    /// The diameter of the smallest sphere about the centroid holding the particle.
    Circumscribed,
}

impl SizeMeasure {
    /// A template's size at scale 1.
    pub fn of(self, s: &Shape) -> f64 {
        match self {
            SizeMeasure::Equivalent => equivalent_diameter(s.volume),
            SizeMeasure::Circumscribed => 2.0 * s.radius,
        }
    }
}

/// How to make a specimen.
#[derive(Clone, Debug, Serialize)]
pub struct Params {
    pub container: Container,
    /// The cylinder's diameter, m.
    pub diameter: f64,
    /// The box's sides along x and y, m.
    pub width: f64,
    pub depth: f64,
    /// The container's height, m.
    pub height: f64,
    /// Particle sizes, uniform between these, m.
    pub size_min: f64,
    pub size_max: f64,
    pub size_measure: SizeMeasure,
    /// Particle count; `None`: as many as fill the container at `porosity`.
    pub count: Option<usize>,
    /// The porosity the count is worked out for.
    pub porosity: f64,
    /// Isotropic consolidation stress, Pa.
    pub pressure: f64,
    /// Particle friction during compaction.
    pub prep_friction: f64,
    /// Local damping during the preparation (compaction and equilibrium).
    pub prep_damping: f64,
    /// The specimen's material (its friction from step 4 on, its damping in the state written).
    pub material: Material,
    pub seed: u64,
    /// Time step over the critical one.
    pub safety: f64,
    /// Scale each body's mass and moments during the preparation so that every body's
    /// critical step is the largest body's (see [`scale_inertia`]); the true ones come back
    /// before the state is written.
    pub inertia_scaling: bool,
    /// Largest relative difference of a wall's stress from `pressure` at the end.
    pub tolerance: f64,
    /// Unbalanced-force ratio that ends compaction, and the one that ends the preparation.
    pub prep_unbalanced: f64,
    pub unbalanced: f64,
    /// Share of the cloud's container the particles fill.
    pub cloud_fraction: f64,
    /// The walls' fastest strain rate, 1/s.
    pub max_strain_rate: f64,
    /// The fastest strain rate while the cloud is loose (fewer particle-particle contacts than
    /// particles), 1/s: the walls then meet single grains, whose impacts the servo would take
    /// for stress.
    pub loose_strain_rate: f64,
    /// Servo gain (PFC's alpha), 0 to 1.
    pub gain: f64,
    /// Integral time of the compaction's servo, in steps (see [`servo`]); 0: none.
    pub integral_steps: u64,
    /// Steps allowed in all.
    pub max_steps: u64,
    /// Flat facets of the cylinder wall.
    pub segments: u32,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            container: Container::Cylinder,
            diameter: 0.3,
            width: 0.3,
            depth: 0.3,
            height: 0.6,
            size_min: 0.010,
            size_max: 0.040,
            size_measure: SizeMeasure::Equivalent,
            count: None,
            porosity: 0.4,
            pressure: 100e3,
            prep_friction: 0.1,
            prep_damping: 0.3,
            material: Material::default(),
            seed: 1,
            safety: 0.2,
            inertia_scaling: true,
            tolerance: 0.02,
            prep_unbalanced: 1e-2,
            unbalanced: 1e-3,
            cloud_fraction: 0.2,
            max_strain_rate: 4.0,
            loose_strain_rate: 20.0,
            gain: 0.5,
            integral_steps: 2000,
            max_steps: 2_000_000,
            segments: 128,
        }
    }
}

/// Why no specimen.
#[derive(Debug, Error, PartialEq)]
pub enum PackError {
    #[error(transparent)]
    TimeStep(#[from] crate::dem::world::TimeStepError),
    #[error("no templates (expected an OBJ stream of particle shapes)")]
    NoTemplates,
    /// A parameter out of its range: the [`Params`] field (or the function's argument) and
    /// what it must be.
    #[error("{field} {rule}")]
    Param { field: &'static str, rule: String },
    #[error("{0}")]
    Bad(String),
    #[error("{0}")]
    Journal(String),
    #[error("a particle of size {size} m ({measure:?}) spans {span:.4} m, more than the container's {what} of {limit} m")]
    TooLarge {
        size: f64,
        measure: SizeMeasure,
        span: f64,
        what: &'static str,
        limit: f64,
    },
    #[error("could not place particle {0} of the loose cloud without overlap after {1} tries, even in a container twice the size")]
    Crowded(usize, usize),
    #[error("not in equilibrium after {steps} steps ({phase}): wall stresses {stresses:?} Pa against {target} Pa, unbalanced-force ratio {unbalanced:.3e}")]
    NotSettled {
        steps: u64,
        phase: &'static str,
        stresses: Vec<f64>,
        target: f64,
        unbalanced: f64,
    },
}

impl Params {
    /// The servo law of the preparation's walls.
    pub fn servo_law(&self) -> ServoLaw {
        ServoLaw {
            pressure: self.pressure,
            gain: self.gain,
            max_strain_rate: self.max_strain_rate,
            loose_strain_rate: self.loose_strain_rate,
            integral_steps: self.integral_steps,
            tolerance: self.tolerance,
        }
    }

    fn check(&self) -> Result<(), PackError> {
        let across = match self.container {
            Container::Cylinder => vec![("diameter", self.diameter)],
            Container::Box => vec![("width", self.width), ("depth", self.depth)],
        };
        let positive = across.into_iter().chain([
            ("height", self.height),
            ("size_min", self.size_min),
            ("size_max", self.size_max),
            ("pressure", self.pressure),
            ("max_strain_rate", self.max_strain_rate),
            ("loose_strain_rate", self.loose_strain_rate),
            ("unbalanced", self.unbalanced),
            ("prep_unbalanced", self.prep_unbalanced),
            ("tolerance", self.tolerance),
        ]);
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                return Err(PackError::Param {
                    field: name,
                    rule: format!("must be a positive number, got {v}"),
                });
            }
        }
        if self.size_min > self.size_max {
            return Err(PackError::Param {
                field: "size_min",
                rule: format!(
                    "{} is above the largest size {}",
                    self.size_min, self.size_max
                ),
            });
        }
        let unit = [
            ("porosity", self.porosity, false),
            ("cloud_fraction", self.cloud_fraction, false),
            ("prep_damping", self.prep_damping, true),
            ("gain", self.gain, false),
            ("safety", self.safety, false),
        ];
        for (name, v, zero) in unit {
            let ok = if zero {
                (0.0..1.0).contains(&v)
            } else {
                v > 0.0 && v < 1.0
            };
            if !ok {
                return Err(PackError::Param {
                    field: name,
                    rule: format!("must be in (0, 1), got {v}"),
                });
            }
        }
        if !(self.prep_friction >= 0.0 && self.prep_friction.is_finite()) {
            return Err(PackError::Param {
                field: "prep_friction",
                rule: format!(
                    "must be a friction coefficient of 0 or more, got {}",
                    self.prep_friction
                ),
            });
        }
        if self.count == Some(0) {
            return Err(PackError::Param {
                field: "count",
                rule: "must be at least 1".into(),
            });
        }
        if self.count.is_some_and(|n| n > MAX_PARTICLES) {
            return Err(PackError::Param {
                field: "count",
                rule: format!("must be at most {MAX_PARTICLES}"),
            });
        }
        if !(16..=MAX_SEGMENTS).contains(&self.segments) {
            return Err(PackError::Param {
                field: "segments",
                rule: format!("must be 16 to {MAX_SEGMENTS}, got {}", self.segments),
            });
        }
        // The pressure's force on a largest particle, about p d^2, presses it into a
        // neighbour by p d^2 / kn: beyond a few per cent of d the contact law of rigid bodies
        // describes nothing, and the overlaps outgrow the particles.
        let overlap = self.pressure * self.size_max / self.material.kn;
        if overlap > MAX_PRESSURE_OVERLAP {
            return Err(PackError::Param {
                field: "pressure",
                rule: format!(
                    "{:e} Pa would press a largest particle ({} m) into its neighbours by about \
                     {:.3e} of its size at kn {:e} N/m (p d / kn); at most {MAX_PRESSURE_OVERLAP} \
                     is modelled",
                    self.pressure, self.size_max, overlap, self.material.kn
                ),
            });
        }
        Ok(())
    }

    /// The container's inside as asked for, z from 0 to the height.
    fn bounds(&self) -> Bounds {
        let section = match self.container {
            Container::Cylinder => Section::Circle {
                radius: 0.5 * self.diameter,
                segments: self.segments,
            },
            Container::Box => Section::Rect {
                x: [-0.5 * self.width, 0.5 * self.width],
                y: [-0.5 * self.depth, 0.5 * self.depth],
            },
        };
        Bounds {
            section,
            bottom: 0.0,
            top: self.height,
        }
    }

    /// The container's sizes across with the options that set them, for [`PackError::TooLarge`].
    fn spans(&self) -> Vec<(&'static str, f64)> {
        match self.container {
            Container::Cylinder => vec![("diameter", self.diameter), ("height", self.height)],
            Container::Box => vec![
                ("width", self.width),
                ("depth", self.depth),
                ("height", self.height),
            ],
        }
    }
}

/// The most particles a specimen may have.
pub const MAX_PARTICLES: usize = 1_000_000;

/// The loose cloud (steps 1 and 2): bodies in an enlarged container, nothing touching, the
/// preparation's friction and damping, no gravity, time step `safety` x critical.
pub fn cloud(templates: Vec<Shape>, p: &Params) -> Result<World, PackError> {
    p.check()?;
    if templates.is_empty() {
        return Err(PackError::NoTemplates);
    }
    let t = templates.len();
    let mut rng = ChaCha8Rng::seed_from_u64(p.seed);
    // Step 1: (template, scale), drawn in order.
    let bounds = p.bounds();
    let target = (1.0 - p.porosity) * bounds.area() * bounds.height();
    let mut picks: Vec<(u32, f64)> = Vec::new();
    let mut solid = 0.0;
    loop {
        let done = match p.count {
            Some(n) => picks.len() >= n,
            None => solid >= target && picks.len() % t == 0,
        };
        if done {
            break;
        }
        if picks.len() == MAX_PARTICLES {
            return Err(PackError::Bad(format!(
                "more than {MAX_PARTICLES} particles would fill the container: \
                 raise the smallest size or shrink the container"
            )));
        }
        let shape = (picks.len() % t) as u32;
        let s = &templates[shape as usize];
        let size = if p.size_max > p.size_min {
            rng.random_range(p.size_min..p.size_max)
        } else {
            p.size_min
        };
        let scale = size / p.size_measure.of(s);
        solid += s.volume * cube(scale);
        picks.push((shape, scale));
    }
    // The largest particle must fit the container.
    let span = |&(shape, scale): &(u32, f64)| 2.0 * templates[shape as usize].radius * scale;
    let widest = picks.iter().map(span).fold(0.0, f64::max);
    for (what, limit) in p.spans() {
        if widest >= limit {
            let (shape, scale) = *picks.iter().find(|x| span(x) == widest).expect("widest");
            return Err(PackError::TooLarge {
                size: scale * p.size_measure.of(&templates[shape as usize]),
                measure: p.size_measure,
                span: widest,
                what,
                limit,
            });
        }
    }
    // Step 2: the cloud's container, and the particles in it, largest first. Where they do
    // not fit (a small container's walls leave less room), the container grows by 5 % and the
    // placing starts again, up to twice the first size.
    let first = (solid / p.cloud_fraction / (bounds.area() * bounds.height()))
        .cbrt()
        .max(1.0);
    let mut grow = first;
    let poses = loop {
        // Inside a cylinder's facets: inside the circle inscribed in them.
        let mut region = bounds.scaled(grow);
        if let Section::Circle { radius, segments } = &mut region.section {
            *radius *= (PI / f64::from(*segments)).cos();
        }
        match place(&templates, &picks, &region, p, &mut rng) {
            Ok(poses) => break poses,
            Err(_) if grow < 2.0 * first => grow *= 1.05,
            Err(i) => return Err(PackError::Crowded(i, TRIES)),
        }
    };
    let material = Material {
        friction: p.prep_friction,
        damping: p.prep_damping,
        ..p.material
    };
    let mut w = World::new(material, Vec3::zeros());
    for s in templates {
        w.add_shape(s);
    }
    for (&(shape, scale), &(c, rot)) in picks.iter().zip(&poses) {
        w.add_body(shape, scale, c, rot);
    }
    w.walls = bounds.scaled(grow).walls();
    if p.inertia_scaling {
        scale_inertia(&mut w);
    }
    w.dt = w.time_step(p.safety)?;
    Ok(w)
}

/// The most facets of the cylinder (its cost grows with them; 128 is the default).
pub const MAX_SEGMENTS: u32 = 10_000;

/// The largest overlap, as a share of the largest particle's size, that the pressure may make
/// (p d / kn): the defaults make 4e-5.
pub const MAX_PRESSURE_OVERLAP: f64 = 0.05;

/// Tries per particle before [`place`] gives up.
const TRIES: usize = 20_000;

/// Uniformly random poses for `picks` (template, scale), largest first, inside `region`, clear
/// of its walls and of each other by a thousandth of the smallest size; `Err(i)` when particle
/// `i` found no room in [`TRIES`] tries.
fn place(
    templates: &[Shape],
    picks: &[(u32, f64)],
    region: &Bounds,
    p: &Params,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<(Vec3, UnitQuaternion<f64>)>, usize> {
    let radii: Vec<f64> = (picks.iter())
        .map(|&(shape, scale)| templates[shape as usize].radius * scale)
        .collect();
    let widest = 2.0 * radii.iter().copied().fold(0.0, f64::max);
    let gap = 1e-3 * p.size_min;
    let mut order: Vec<usize> = (0..picks.len()).collect();
    order.sort_by(|&a, &b| radii[b].total_cmp(&radii[a]).then(a.cmp(&b)));
    // A grid cell as wide as the widest particle: particles that may overlap are in
    // neighbouring cells.
    let cell = widest.max(1e-12);
    let key = |x: &Vec3| {
        (
            (x.x / cell).floor() as i64,
            (x.y / cell).floor() as i64,
            (x.z / cell).floor() as i64,
        )
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<usize>> = HashMap::new();
    let mut poses = vec![(Vec3::zeros(), UnitQuaternion::identity()); picks.len()];
    let mut corners: Vec<Vec<Vec3>> = vec![Vec::new(); picks.len()];
    for &i in &order {
        let (shape, scale) = picks[i];
        let s = &templates[shape as usize];
        let r = radii[i];
        let mut tries = 0;
        let (c, rot, verts) = loop {
            if tries == TRIES {
                return Err(i);
            }
            tries += 1;
            let rot = random_rotation(rng);
            let c = region.draw(rng);
            let verts: Vec<Vec3> = s.vertices.iter().map(|v| c + rot * (v * scale)).collect();
            let inside = verts.iter().all(|x| region.holds(x, gap));
            if !inside {
                continue;
            }
            let (kx, ky, kz) = key(&c);
            let clear = (-1..=1).all(|dx| {
                (-1..=1).all(|dy| {
                    (-1..=1).all(|dz| {
                        grid.get(&(kx + dx, ky + dy, kz + dz)).is_none_or(|near| {
                            near.iter().all(|&j| {
                                let d = poses[j].0 - c;
                                d.norm_squared() > square(r + radii[j] + gap)
                                    || gjk::separated(&verts, &corners[j], &d, gap)
                            })
                        })
                    })
                })
            });
            if clear {
                break (c, rot, verts);
            }
        };
        poses[i] = (c, rot);
        corners[i] = verts;
        grid.entry(key(&c)).or_default().push(i);
    }
    Ok(poses)
}

/// Where a preparation is, for progress reports.
#[derive(Clone, Debug)]
pub struct Status {
    pub phase: &'static str,
    pub step: u64,
    /// Every wall's stress, Pa (see [`wall_stresses`]).
    pub stresses: Vec<f64>,
    pub porosity: f64,
    pub unbalanced: f64,
}

/// Steps 3 and 4 on a cloud from [`cloud`]: compacts it and brings it to equilibrium;
/// `report` sees the status and the world every `every` steps. The walls and the bodies are
/// at rest at the end.
pub fn consolidate(
    w: &mut World,
    p: &Params,
    every: u64,
    mut report: impl FnMut(&Status, &World) + Send,
) -> Result<(), PackError> {
    let start = w.step;
    phase(w, p, Phase::Compaction, start, every, &mut report)?;
    w.material.friction = p.material.friction;
    phase(w, p, Phase::Equilibrium, start, every, &mut report)?;
    w.material.damping = p.material.damping;
    set_speeds(w, &vec![0.0; w.walls.len()]);
    restore_inertia(w, p.safety);
    at_rest(w);
    Ok(())
}

/// Every body still. Local damping acts only on a body that a force pushes, so a particle
/// without contacts (a rattler, a fifth of a dense specimen of 10-40 mm) keeps the speed and
/// spin the compaction left it, some 1 cm/s against the network's 2e-5 m/s at the paper's
/// scale, and turns freely through a test: the mean rotation then grows with the test's
/// duration rather than its strain (docs/models/pack.md, "The specimen at rest").
///
/// The kinetic energy taken out counts as damped, so that the ledger's balance does not move.
fn at_rest(w: &mut World) {
    let kinetic: f64 = w.bodies.iter().map(|b| b.kinetic_energy()).sum();
    for b in &mut w.bodies {
        b.vel = Vec3::zeros();
        b.ang_mom = Vec3::zeros();
    }
    w.energy.damping += kinetic;
    w.energy.kinetic = 0.0;
}

/// Step 3 alone (for [`calibrate`]); the walls are left moving.
pub fn compact(
    w: &mut World,
    p: &Params,
    every: u64,
    mut report: impl FnMut(&Status, &World) + Send,
) -> Result<(), PackError> {
    phase(w, p, Phase::Compaction, w.step, every, &mut report)
}

/// Compaction also ends at the target mean stress when the porosity has changed by less than
/// `PLATEAU_POROSITY` over the last `(PLATEAU_SAMPLES - 1) x PLATEAU_EVERY` steps.
const PLATEAU_EVERY: u64 = 1000;
const PLATEAU_SAMPLES: usize = 11;
const PLATEAU_POROSITY: f64 = 1e-4;

/// The two stages of [`consolidate`].
#[derive(Clone, Copy, PartialEq, Eq)]
enum Phase {
    Compaction,
    Equilibrium,
}

/// Runs one stage until it ends (see the module's steps 3 and 4); steps count from `start`.
fn phase(
    w: &mut World,
    p: &Params,
    which: Phase,
    start: u64,
    every: u64,
    report: &mut (impl FnMut(&Status, &World) + Send),
) -> Result<(), PackError> {
    // The steps run on the pool (see `on_pool`).
    crate::dem::parallel::on_pool(|| {
        let (name, unbalanced) = match which {
            Phase::Compaction => ("compaction", p.prep_unbalanced),
            Phase::Equilibrium => ("equilibrium", p.unbalanced),
        };
        // Porosity every PLATEAU_EVERY steps, the last PLATEAU_SAMPLES of them.
        let mut history: std::collections::VecDeque<f64> = std::collections::VecDeque::new();
        // The bodies' volume does not change: summed once, not every step.
        let solid = solid_volume(w);
        // The compaction servo's integral term, Pa.
        let mut integral = 0.0;
        loop {
            // The container as the walls have it this step.
            let b = bounds(w);
            let geometry = b.geometry();
            let (stresses, counts) = stresses_in(w, &b, &geometry);
            let status = Status {
                phase: name,
                step: w.step - start,
                stresses: stresses.clone(),
                porosity: porosity_of(&b, solid),
                unbalanced: w.unbalanced,
            };
            if status.step % every == 0 {
                report(&status, w);
            }
            let near = |s: f64| (s - p.pressure).abs() <= p.tolerance * p.pressure;
            if status.step % PLATEAU_EVERY == 0 {
                history.push_back(status.porosity);
                if history.len() > PLATEAU_SAMPLES {
                    history.pop_front();
                }
            }
            let done = match which {
                Phase::Compaction => {
                    // At the target mean stress, and either in balance or no longer compacting
                    // (a frictionless packing keeps sliding at the target without densifying).
                    let plateau = history.len() == PLATEAU_SAMPLES
                        && (history[0] - status.porosity).abs() < PLATEAU_POROSITY;
                    let mean = mean_stress(&geometry, &stresses);
                    near(mean) && (w.unbalanced <= unbalanced || plateau)
                }
                Phase::Equilibrium => {
                    stresses.iter().all(|&s| near(s)) && w.unbalanced <= unbalanced
                }
            };
            if done {
                return Ok(());
            }
            if status.step >= p.max_steps {
                return Err(PackError::NotSettled {
                    steps: status.step,
                    phase: name,
                    stresses,
                    target: p.pressure,
                    unbalanced: w.unbalanced,
                });
            }
            let common = (which == Phase::Compaction).then_some(&mut integral);
            let speeds = servo(w, &p.servo_law(), &geometry, &stresses, &counts, common);
            set_speeds(w, &speeds);
            w.step();
        }
    })
}

/// The void-ratio limits of the templates and sizes, and the preparation friction for a relative
/// density, found on a smaller sample (docs/models/pack.md, "Relative density").
#[derive(Clone, Debug, Serialize)]
pub struct Calibration {
    /// The sample's limits (its scale, particles, e_min, e_max, loose friction).
    #[serde(flatten)]
    pub limits: Limits,
    /// The target, and the preparation friction chosen for it.
    pub relative_density: f64,
    pub prep_friction: f64,
    /// Every compaction run: (preparation friction, void ratio), in the order run.
    pub runs: Vec<(f64, f64)>,
}

/// The next preparation friction to try for void ratio `target`, between the frictions `lo`
/// (its void ratio at most `target`) and `hi` (at least): linear interpolation in the square
/// root of the friction, where the void ratio rises steeply near 0 and flattens.
pub fn next_friction(lo: (f64, f64), hi: (f64, f64), target: f64) -> f64 {
    let (a, b) = (lo.0.sqrt(), hi.0.sqrt());
    let t = if hi.1 > lo.1 {
        ((target - lo.1) / (hi.1 - lo.1)).clamp(0.0, 1.0)
    } else {
        0.5
    };
    square(a + t * (b - a))
}

/// The container scaled by `scale` in each direction, with the same templates, sizes and seed
/// (and a `count` scaled by the volume): [`calibrate`]'s and [`void_limits`]' sample.
fn sample(p: &Params, scale: f64) -> Result<Params, PackError> {
    if !(scale > 0.0 && scale <= 1.0) {
        return Err(PackError::Param {
            field: "calibration_scale",
            rule: format!("must be in (0, 1], got {scale}"),
        });
    }
    Ok(Params {
        diameter: p.diameter * scale,
        width: p.width * scale,
        depth: p.depth * scale,
        height: p.height * scale,
        count: p
            .count
            .map(|n| ((n as f64 * cube(scale)).round() as usize).max(1)),
        ..p.clone()
    })
}

/// The particle count and void ratio at the end of compaction (step 3) of `sample` at
/// preparation `friction`, from `journal` if it holds that compaction, else run and recorded
/// there; `report` sees the friction and status of a run.
fn compacted(
    templates: &[Shape],
    sample: &Params,
    friction: f64,
    every: u64,
    journal: &mut Journal,
    report: &mut (impl FnMut(f64, &Status) + Send),
) -> Result<(usize, f64), PackError> {
    let q = Params {
        prep_friction: friction,
        ..sample.clone()
    };
    let key = journal.key(templates, &q);
    if let Some(&found) = journal.done.get(&key) {
        report(
            friction,
            &Status {
                phase: REUSED,
                step: 0,
                stresses: Vec::new(),
                porosity: found.1 / (1.0 + found.1),
                unbalanced: f64::NAN,
            },
        );
        return Ok(found);
    }
    let mut w = cloud(templates.to_vec(), &q)?;
    compact(&mut w, &q, every, |s, _| report(friction, s))?;
    let n = porosity(&w);
    let found = (w.bodies.len(), n / (1.0 - n));
    journal.record(key, &q, found)?;
    Ok(found)
}

/// The phase [`Status`] reports for a compaction taken from the [`Journal`] (once, at step 0).
pub const REUSED: &str = "journal";

/// The compactions a preparation has run ([`void_limits`], [`calibrate`], [`refine`]), kept
/// so that a stopped preparation started again takes the runs it finished instead of running
/// them again, with the same result to the bit. Each compaction is a JSON line (its fields in
/// [`JournalLine`]), keyed by a fingerprint of the templates and every parameter of the run,
/// so lines of other runs are passed over. The key does not cover the engine's code: a journal
/// is for the build that wrote it.
#[derive(Default)]
pub struct Journal<'a> {
    done: HashMap<String, (usize, f64)>,
    sink: Option<&'a mut dyn std::io::Write>,
}

/// One compaction in a [`Journal`].
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct JournalLine {
    /// The fingerprint of the templates and the run's parameters (16 hex digits).
    pub key: String,
    /// The preparation friction and the container's height, for a reader.
    pub friction: f64,
    pub height: f64,
    pub particles: usize,
    pub void_ratio: f64,
}

impl<'a> Journal<'a> {
    /// A journal holding the compactions in `text` (JSON lines), writing new ones to `sink`.
    /// A last line cut short (a run stopped while writing it) is passed over; any other line
    /// that is not a compaction is an error naming the line.
    pub fn new(text: &str, sink: Option<&'a mut dyn std::io::Write>) -> Result<Self, PackError> {
        let mut done = HashMap::new();
        let lines: Vec<&str> = text.split_inclusive('\n').collect();
        for (i, line) in lines.iter().enumerate() {
            if line.trim().is_empty() {
                continue;
            }
            match serde_json::from_str::<JournalLine>(line) {
                Ok(l) => {
                    done.insert(l.key, (l.particles, l.void_ratio));
                }
                Err(_) if i + 1 == lines.len() && !line.ends_with('\n') => {}
                Err(e) => {
                    return Err(PackError::Journal(format!(
                        "journal line {} is not a compaction ({e}): {}",
                        i + 1,
                        line.trim_end()
                    )))
                }
            }
        }
        Ok(Journal { done, sink })
    }

    /// The key of a compaction of `templates` under `p`: FNV-1a over each template's name,
    /// vertices and faces, and `p` as JSON (its floats written to the bit).
    fn key(&self, templates: &[Shape], p: &Params) -> String {
        let mut h = Fnv::default();
        for t in templates {
            h.bytes(t.name.as_bytes());
            for v in &t.vertices {
                for x in v.iter() {
                    h.bytes(&x.to_bits().to_le_bytes());
                }
            }
            for &i in t.face_start.iter().chain(&t.face_verts) {
                h.bytes(&i.to_le_bytes());
            }
        }
        h.bytes(serde_json::to_string(p).unwrap_or_default().as_bytes());
        format!("{:016x}", h.0)
    }

    fn record(&mut self, key: String, p: &Params, found: (usize, f64)) -> Result<(), PackError> {
        self.done.insert(key.clone(), found);
        let Some(sink) = self.sink.as_mut() else {
            return Ok(());
        };
        let line = JournalLine {
            key,
            friction: p.prep_friction,
            height: p.height,
            particles: found.0,
            void_ratio: found.1,
        };
        let mut text =
            serde_json::to_string(&line).map_err(|e| PackError::Journal(e.to_string()))?;
        text.push('\n');
        sink.write_all(text.as_bytes())
            .and_then(|()| sink.flush())
            .map_err(|e| PackError::Journal(format!("writing the journal: {e}")))
    }
}

/// The 64-bit FNV-1a hash, stable across builds and platforms (the journal's keys).
struct Fnv(u64);

impl Default for Fnv {
    fn default() -> Self {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv {
    fn bytes(&mut self, b: &[u8]) {
        for &x in b {
            self.0 = (self.0 ^ u64::from(x)).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
}

fn check_loose(loose_friction: f64) -> Result<(), PackError> {
    if loose_friction > 0.0 && loose_friction.is_finite() {
        Ok(())
    } else {
        Err(PackError::Param {
            field: "loose_friction",
            rule: format!("must be a positive friction coefficient, got {loose_friction}"),
        })
    }
}

/// The void-ratio limits alone, measured on the container scaled by `scale` (1: the
/// specimen's own): compactions at friction 0 (e_min) and at `loose_friction` (e_max).
#[derive(Clone, Debug, Serialize)]
pub struct Limits {
    /// The sample's container over the specimen's, in each direction.
    pub scale: f64,
    pub particles: usize,
    /// Void ratio after compaction without friction (the densest) and at `loose_friction`.
    pub e_min: f64,
    pub e_max: f64,
    pub loose_friction: f64,
}

/// [`Limits`] of `templates` and `p` on the container scaled by `scale`.
pub fn void_limits(
    templates: &[Shape],
    p: &Params,
    scale: f64,
    loose_friction: f64,
    every: u64,
    journal: &mut Journal,
    mut report: impl FnMut(f64, &Status) + Send,
) -> Result<Limits, PackError> {
    limits_of(
        templates,
        &sample(p, scale)?,
        scale,
        loose_friction,
        every,
        journal,
        &mut report,
    )
}

/// [`void_limits`] on the `sample` made by [`sample`] at `scale`.
fn limits_of(
    templates: &[Shape],
    sample: &Params,
    scale: f64,
    loose_friction: f64,
    every: u64,
    journal: &mut Journal,
    report: &mut (impl FnMut(f64, &Status) + Send),
) -> Result<Limits, PackError> {
    check_loose(loose_friction)?;
    let (_, e_min) = compacted(templates, sample, 0.0, every, journal, report)?;
    let (particles, e_max) = compacted(templates, sample, loose_friction, every, journal, report)?;
    Ok(Limits {
        scale,
        particles,
        e_min,
        e_max,
        loose_friction,
    })
}

/// Finds e_min, e_max and the preparation friction for `relative_density` on a sample of the
/// container scaled by `scale` (the same templates, sizes and seed), by compacting it at friction
/// 0, at `loose_friction`, and then `extra` times at [`next_friction`] within the bracket.
/// `report` sees each run's friction and status.
#[allow(clippy::too_many_arguments)]
pub fn calibrate(
    templates: &[Shape],
    p: &Params,
    relative_density: f64,
    scale: f64,
    loose_friction: f64,
    extra: usize,
    every: u64,
    journal: &mut Journal,
    mut report: impl FnMut(f64, &Status) + Send,
) -> Result<Calibration, PackError> {
    if !(0.0..=1.0).contains(&relative_density) {
        return Err(PackError::Param {
            field: "relative_density",
            rule: format!("must be in [0, 1], got {relative_density}"),
        });
    }
    let sample = sample(p, scale)?;
    let limits = limits_of(
        templates,
        &sample,
        scale,
        loose_friction,
        every,
        journal,
        &mut report,
    )?;
    let (e_min, e_max) = (limits.e_min, limits.e_max);
    let mut runs = vec![(0.0, e_min), (loose_friction, e_max)];
    let target = e_max - relative_density * (e_max - e_min);
    let (mut lo, mut hi) = (runs[0], runs[1]);
    for _ in 0..extra {
        let f = next_friction(lo, hi, target);
        let (_, e) = compacted(templates, &sample, f, every, journal, &mut report)?;
        runs.push((f, e));
        if e <= target {
            lo = (f, e);
        } else {
            hi = (f, e);
        }
    }
    Ok(Calibration {
        limits,
        relative_density,
        prep_friction: next_friction(lo, hi, target),
        runs,
    })
}

/// The sample's void ratio at preparation friction `f` by its calibration `runs`, linear in
/// the square root of the friction between the runs on either side (the ends carried flat
/// beyond the first and last).
fn sample_void_ratio(runs: &[(f64, f64)], f: f64) -> f64 {
    let mut sorted = runs.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let x = f.sqrt();
    match sorted.iter().position(|r| r.0 >= f) {
        None => sorted.last().map_or(f64::NAN, |r| r.1),
        Some(0) => sorted[0].1,
        Some(k) => {
            let ((f0, e0), (f1, e1)) = (sorted[k - 1], sorted[k]);
            let (x0, x1) = (f0.sqrt(), f1.sqrt());
            e0 + (e1 - e0) * (x - x0) / (x1 - x0)
        }
    }
}

/// The preparation friction at which the sample's calibration `runs` give void ratio
/// `target`: between the two runs whose void ratios bracket it, by [`next_friction`] (the
/// sample's curve rises with friction; runs that do not are passed over); the nearest end's
/// friction when none do.
fn sample_friction(runs: &[(f64, f64)], target: f64) -> f64 {
    let mut sorted = runs.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    for w in sorted.windows(2) {
        let (lo, hi) = (w[0], w[1]);
        if lo.1 <= target && target <= hi.1 && lo.1 < hi.1 {
            return next_friction(lo, hi, target);
        }
    }
    let first = sorted.first().copied().unwrap_or((0.0, 0.0));
    let last = sorted.last().copied().unwrap_or(first);
    if target < first.1 {
        first.0
    } else {
        last.0
    }
}

/// Full-scale compactions that correct the friction a sample chose ([`calibrate`]) for limits
/// measured at the specimen's own size.
#[derive(Clone, Debug, Serialize)]
pub struct Refinement {
    /// The target void ratio at full scale: `e_max - Dr (e_max - e_min)` of the given limits.
    pub target: f64,
    /// Each full-scale compaction: (preparation friction, void ratio), in the order run.
    pub runs: Vec<(f64, f64)>,
    /// The friction the specimen is made at.
    pub prep_friction: f64,
}

/// Corrects `calibration`'s friction for the specimen's own `limits` (e_min, e_max at its size)
/// by `runs` compactions of the specimen itself. The specimen packs denser than the sample at
/// any friction (its wall is a smaller share), by about the same void ratio over the range
/// that matters (I_P: 0.068 at friction 0.1, 0.073 at 0.067): each run measures
/// that offset at the friction it was made at, and the next friction is the one at which the
/// sample's curve (its calibration runs) reaches the full-scale target plus the offset.
#[allow(clippy::too_many_arguments)]
pub fn refine(
    templates: &[Shape],
    p: &Params,
    calibration: &Calibration,
    limits: (f64, f64),
    runs: usize,
    every: u64,
    journal: &mut Journal,
    mut report: impl FnMut(f64, &Status) + Send,
) -> Result<Refinement, PackError> {
    let (e_min, e_max) = limits;
    let target = e_max - calibration.relative_density * (e_max - e_min);
    let mut f = calibration.prep_friction;
    let mut done = Vec::with_capacity(runs);
    for _ in 0..runs {
        let (_, e) = compacted(templates, p, f, every, journal, &mut report)?;
        done.push((f, e));
        let offset = e - sample_void_ratio(&calibration.runs, f);
        f = sample_friction(&calibration.runs, target - offset);
    }
    Ok(Refinement {
        target,
        runs: done,
        prep_friction: f,
    })
}

/// What a specimen is: the summary `pack` reports.
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub particles: usize,
    pub templates: usize,
    pub container: Container,
    /// The container at the end, m: the cylinder's diameter (its radius x 2), or the box's
    /// sides along x and y; the platens' distance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diameter: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub width: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub depth: Option<f64>,
    pub height: f64,
    pub porosity: f64,
    pub void_ratio: f64,
    /// The void ratio of the core, one largest particle (`size_max`) in from every wall
    /// ([`core_porosity`]): without the looser layer along the walls. `None` when that leaves
    /// no core.
    pub core_void_ratio: Option<f64>,
    /// Particle-particle contacts x 2 over particles.
    pub coordination: f64,
    /// The same without rattlers (particles of fewer than two particle contacts):
    /// (2 C - N1) / (N - N0 - N1), C the particle-particle contacts.
    pub mechanical_coordination: f64,
    /// Every wall's stress in the walls' order (see [`Container`]), Pa, and the largest relative
    /// difference from the target.
    pub wall_stresses: Vec<f64>,
    pub stress_error: f64,
    pub unbalanced: f64,
    /// Deviatoric anisotropy of the particle-particle contact normals: (15/2) sqrt(3/2 d:d),
    /// d the deviator of the fabric tensor <n n> (a_c of the paper's Fig. 17; 0 isotropic).
    pub anisotropy: f64,
    /// The root-mean-square `anisotropy` of as many independent, isotropic random normals as
    /// there are particle-particle contacts, `7.5 / sqrt(C)`: sampling alone gives that much,
    /// so a smaller `anisotropy` is zero within sampling. `None` without contacts.
    pub anisotropy_noise: Option<f64>,
    /// Largest contact depth over the size (equivalent-sphere diameter) of the smaller body.
    pub max_overlap: f64,
    /// Particles reaching out of the container by more than 1 % of their size.
    pub outside: usize,
    pub contacts: usize,
    pub steps: u64,
    pub time: f64,
    pub dt: f64,
}

/// The summary of specimen `w` made with `p`.
pub fn summary(w: &World, p: &Params) -> Summary {
    let n = w.bodies.len();
    let inside = bounds(w);
    let size = |b: usize| {
        let body = &w.bodies[b];
        equivalent_diameter(w.shapes[body.shape as usize].volume) * body.scale
    };
    let (mut pairs, mut fabric, mut max_overlap) = (0usize, nalgebra::Matrix3::zeros(), 0.0f64);
    for (&(partner, b), c) in &w.contacts {
        let smaller = match partner {
            Partner::Body(a) => {
                pairs += 1;
                fabric += c.normal * c.normal.transpose();
                size(a as usize).min(size(b as usize))
            }
            Partner::Wall(_) => size(b as usize),
        };
        max_overlap = max_overlap.max(c.depth / smaller);
    }
    let anisotropy = anisotropy(&fabric, pairs);
    let outside = (0..n)
        .filter(|&b| {
            let body = &w.bodies[b];
            let slack = 0.01 * size(b);
            w.shapes[body.shape as usize].vertices.iter().any(|v| {
                let x = body.pos + body.rot * (v * body.scale);
                !inside.holds(&x, -slack)
            })
        })
        .count();
    let (stresses, _) = wall_stresses(w);
    let phi = porosity(w);
    let (coordination, mechanical_coordination) = coordination(w);
    Summary {
        particles: n,
        templates: w.shapes.len(),
        container: match inside.section {
            Section::Circle { .. } => Container::Cylinder,
            Section::Rect { .. } => Container::Box,
        },
        diameter: match inside.section {
            Section::Circle { radius, .. } => Some(2.0 * radius),
            Section::Rect { .. } => None,
        },
        width: match inside.section {
            Section::Rect { x, .. } => Some(x[1] - x[0]),
            Section::Circle { .. } => None,
        },
        depth: match inside.section {
            Section::Rect { y, .. } => Some(y[1] - y[0]),
            Section::Circle { .. } => None,
        },
        height: inside.height(),
        porosity: phi,
        void_ratio: phi / (1.0 - phi),
        core_void_ratio: core_porosity(w, p.size_max).map(|c| c / (1.0 - c)),
        coordination,
        mechanical_coordination,
        stress_error: stresses
            .iter()
            .map(|s| (s - p.pressure).abs() / p.pressure)
            .fold(0.0, f64::max),
        wall_stresses: stresses,
        unbalanced: w.unbalanced,
        anisotropy,
        anisotropy_noise: (pairs > 0).then(|| 7.5 / (pairs as f64).sqrt()),
        max_overlap,
        outside,
        contacts: w.contacts.len(),
        steps: w.step,
        time: w.time,
        dt: w.dt,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lab::boundary::container;

    #[test]
    fn the_sample_curve_is_read_both_ways_in_the_square_root_of_the_friction() {
        // A measured Ab_1 sample: limits and two runs, out of order as they are run.
        let runs = [(0.0, 0.566), (1.0, 0.959), (0.04, 0.616), (0.072, 0.672)];
        assert_eq!(sample_void_ratio(&runs, 0.04), 0.616);
        assert_eq!(sample_void_ratio(&runs, 0.0), 0.566);
        assert_eq!(sample_void_ratio(&runs, 2.0), 0.959);
        // Between 0.04 and 0.072, linear in sqrt(f).
        let f = crate::math::square((0.04f64.sqrt() + 0.072f64.sqrt()) / 2.0);
        assert!((sample_void_ratio(&runs, f) - 0.644).abs() < 1e-12);
        // And back.
        assert!((sample_friction(&runs, 0.644) - f).abs() < 1e-12);
        for e in [0.57, 0.6, 0.65, 0.7, 0.9] {
            let back = sample_void_ratio(&runs, sample_friction(&runs, e));
            assert!((back - e).abs() < 1e-12, "{e} came back {back}");
        }
        // Outside the sample's range: its ends.
        assert_eq!(sample_friction(&runs, 0.5), 0.0);
        assert_eq!(sample_friction(&runs, 1.2), 1.0);
    }

    #[test]
    fn a_journal_key_changes_with_any_template_or_parameter_and_lines_come_back_to_the_bit() {
        let cube = Shape::from_mesh(&crate::geometry::mesh::cube(0.5)).unwrap();
        let other = Shape::from_mesh(&crate::geometry::mesh::cube(0.6)).unwrap();
        let p = Params::default();
        let j = Journal::default();
        let key = j.key(&[cube.clone()], &p);
        assert_eq!(key.len(), 16);
        assert_eq!(key, j.key(&[cube.clone()], &p));
        let seeded = Params {
            seed: p.seed + 1,
            ..p.clone()
        };
        let rubbed = Params {
            prep_friction: p.prep_friction.next_up(),
            ..p.clone()
        };
        for k in [
            j.key(&[other], &p),
            j.key(&[cube.clone(), cube.clone()], &p),
            j.key(&[cube.clone()], &seeded),
            j.key(&[cube.clone()], &rubbed),
        ] {
            assert_ne!(k, key);
        }
        // A recorded compaction reads back with its void ratio to the bit; a last line cut
        // short is passed over.
        let mut text = Vec::new();
        let mut sink: &mut dyn std::io::Write = &mut text;
        let mut j = Journal::new("", Some(&mut sink)).unwrap();
        let e = 0.1f64 + 0.2;
        j.record(key.clone(), &p, (36, e)).unwrap();
        drop(j);
        let text = String::from_utf8(text).unwrap();
        let cut = format!("{text}{}", &text[..20]);
        let j = Journal::new(&cut, None).unwrap();
        assert_eq!(j.done.get(&key), Some(&(36, e)));
        assert_eq!(j.done.len(), 1);
        let bad = format!("{}{text}", &text[..20]);
        assert!(Journal::new(&format!("{bad}\n"), None).is_err());
    }

    #[test]
    fn next_friction_interpolates_in_the_square_root_and_stays_in_the_bracket() {
        // Halfway in void ratio between frictions 0 and 1: sqrt(f) = 0.5.
        assert!((next_friction((0.0, 0.5), (1.0, 0.9), 0.7) - 0.25).abs() < 1e-12);
        // Targets outside the bracket's void ratios go to its ends.
        assert!((next_friction((0.04, 0.6), (0.64, 0.8), 0.5) - 0.04).abs() < 1e-12);
        assert!((next_friction((0.04, 0.6), (0.64, 0.8), 0.95) - 0.64).abs() < 1e-12);
        // A bracket whose void ratios came out the wrong way (noise): its middle.
        assert!((next_friction((0.0, 0.8), (1.0, 0.7), 0.75) - 0.25).abs() < 1e-12);
    }

    #[test]
    fn the_count_fills_the_container_at_the_porosity_in_equal_numbers() {
        let cube = Shape::from_mesh(&crate::geometry::mesh::cube(0.5)).unwrap();
        // The cylinder's cross-section is its 128 facets' polygon.
        let polygon = 0.5 * 128.0 * crate::math::square(0.05f64) * (2.0 * PI / 128.0).sin();
        for (kind, section) in [(Container::Cylinder, polygon), (Container::Box, 0.1 * 0.08)] {
            let p = Params {
                container: kind,
                diameter: 0.1,
                width: 0.1,
                depth: 0.08,
                height: 0.2,
                size_min: 0.01,
                size_max: 0.02,
                ..Params::default()
            };
            let w = cloud(vec![cube.clone(), cube.clone()], &p).unwrap();
            assert_eq!(w.bodies.len() % 2, 0);
            let solid = solid_volume(&w);
            let room = (1.0 - p.porosity) * section * 0.2;
            // Drawn until the solid fills it: over by less than two of the largest particles.
            assert!(
                solid >= room && solid < room + 2.0 * crate::math::cube(0.02f64),
                "{kind:?}: {solid} {room}"
            );
            // The cloud's container is the specimen's scaled alike in every direction, and holds
            // every corner of every body.
            let b = container(&w).unwrap();
            let f = b.height() / 0.2;
            assert!(f > 1.0);
            approx::assert_relative_eq!(b.area(), section * f * f, max_relative = 1e-12);
            for body in &w.bodies {
                for v in &w.shapes[body.shape as usize].vertices {
                    assert!(b.holds(&(body.pos + body.rot * (v * body.scale)), 0.0));
                }
            }
            // Nothing touches: the first step finds no contact.
            let mut w = w;
            w.step();
            assert_eq!(w.contacts.len(), 0, "{kind:?}");
        }
    }
}
