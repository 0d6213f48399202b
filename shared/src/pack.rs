//! Dense, isotropically consolidated specimens of polyhedra (the `pack` tool).
//!
//! The preparation, step by step (docs/pack.md tells why each choice):
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
//!    walls then stop, the true inertia comes back, and the state is the specimen.
//!
//! Steps 3 and 4 run with density scaling ([`scale_inertia`]) unless `inertia_scaling` is off.

use crate::dem::gjk;
use crate::dem::shape::Shape;
use crate::dem::wall::{Wall, WallKind};
use crate::dem::world::{Material, Partner, World};
use crate::mass::{clipped_volume, equivalent_diameter};
use crate::math::{box_excess, cube, square, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::HashMap;
use std::f64::consts::PI;
use thiserror::Error;

/// The bottom platen's index among the walls (a plane, normal +z).
pub const BOTTOM: usize = 0;
/// The top platen's index (a plane, normal -z).
pub const TOP: usize = 1;
/// The cylinder wall's index; in a box, the first of the four side planes (normals +x, -x,
/// +y, -y).
pub const SIDE: usize = 2;

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
    #[error("no templates (expected an OBJ stream of particle shapes)")]
    NoTemplates,
    #[error("{0}")]
    Bad(String),
    #[error("a particle of size {size} m ({measure:?}) spans {span:.4} m, more than the container's {what} of {limit} m")]
    TooLarge {
        size: f64,
        measure: SizeMeasure,
        span: f64,
        what: &'static str,
        limit: f64,
    },
    #[error("could not place particle {0} of the loose cloud without overlap after {1} tries, even in a container twice the size (lower --cloud-fraction)")]
    Crowded(usize, usize),
    #[error("not in equilibrium after {steps} steps ({phase}): wall stresses {stresses:?} Pa against {target} Pa, unbalanced-force ratio {unbalanced:.3e} (raise --max-steps)")]
    NotSettled {
        steps: u64,
        phase: &'static str,
        stresses: Vec<f64>,
        target: f64,
        unbalanced: f64,
    },
}

impl Params {
    fn check(&self) -> Result<(), PackError> {
        let across = match self.container {
            Container::Cylinder => vec![("--diameter", self.diameter)],
            Container::Box => vec![("--width", self.width), ("--depth", self.depth)],
        };
        let positive = across.into_iter().chain([
            ("--height", self.height),
            ("--size-min", self.size_min),
            ("--size-max", self.size_max),
            ("--pressure", self.pressure),
            ("--max-strain-rate", self.max_strain_rate),
            ("--loose-strain-rate", self.loose_strain_rate),
            ("--unbalanced", self.unbalanced),
            ("--prep-unbalanced", self.prep_unbalanced),
            ("--tolerance", self.tolerance),
        ]);
        for (name, v) in positive {
            if !(v > 0.0 && v.is_finite()) {
                return Err(PackError::Bad(format!(
                    "{name} must be a positive number, got {v}"
                )));
            }
        }
        if self.size_min > self.size_max {
            return Err(PackError::Bad(format!(
                "--size-min {} is above --size-max {}",
                self.size_min, self.size_max
            )));
        }
        let unit = [
            ("--porosity", self.porosity, false),
            ("--cloud-fraction", self.cloud_fraction, false),
            ("--prep-damping", self.prep_damping, true),
            ("--gain", self.gain, false),
            ("--safety", self.safety, false),
        ];
        for (name, v, zero) in unit {
            let ok = if zero {
                (0.0..1.0).contains(&v)
            } else {
                v > 0.0 && v < 1.0
            };
            if !ok {
                return Err(PackError::Bad(format!("{name} must be in (0, 1), got {v}")));
            }
        }
        if !(self.prep_friction >= 0.0 && self.prep_friction.is_finite()) {
            return Err(PackError::Bad(format!(
                "--prep-friction must be a friction coefficient of 0 or more, got {}",
                self.prep_friction
            )));
        }
        if self.count == Some(0) {
            return Err(PackError::Bad("--count must be at least 1".into()));
        }
        if self.count.is_some_and(|n| n > MAX_PARTICLES) {
            return Err(PackError::Bad(format!(
                "--count must be at most {MAX_PARTICLES}"
            )));
        }
        if self.segments < 16 {
            return Err(PackError::Bad(format!(
                "--segments must be at least 16, got {}",
                self.segments
            )));
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

/// A container's cross-section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Section {
    /// The prism of `segments` facets inscribed in the circle of `radius` about the z axis.
    Circle { radius: f64, segments: u32 },
    /// From `x[0]` to `x[1]` and `y[0]` to `y[1]`.
    Rect { x: [f64; 2], y: [f64; 2] },
}

/// A container's inside: its cross-section, from z = `bottom` to `top`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub section: Section,
    pub bottom: f64,
    pub top: f64,
}

/// What the servo needs of one wall: its area, its distance from the container's middle, and
/// its share of the mean stress.
struct WallGeometry {
    area: f64,
    half: f64,
    weight: f64,
}

impl Bounds {
    pub fn height(&self) -> f64 {
        self.top - self.bottom
    }

    /// The cross-section's area (the cylinder's: its facet polygon's).
    pub fn area(&self) -> f64 {
        match self.section {
            Section::Circle { radius, segments } => {
                let n = f64::from(segments);
                0.5 * n * radius * radius * (2.0 * PI / n).sin()
            }
            Section::Rect { x, y } => (x[1] - x[0]) * (y[1] - y[0]),
        }
    }

    /// The cross-section's perimeter (the cylinder's: its facet polygon's).
    fn perimeter(&self) -> f64 {
        match self.section {
            Section::Circle { radius, segments } => {
                let n = f64::from(segments);
                2.0 * n * radius * (PI / n).sin()
            }
            Section::Rect { x, y } => 2.0 * ((x[1] - x[0]) + (y[1] - y[0])),
        }
    }

    /// Whether `x` is inside, at least `margin` from every wall (a negative margin lets it
    /// out by as much). The cylinder's wall is its circle, not its facets.
    pub fn holds(&self, x: &Vec3, margin: f64) -> bool {
        let across = match self.section {
            Section::Circle { radius, .. } => x.xy().norm() < radius - margin,
            Section::Rect { x: xs, y: ys } => {
                x.x > xs[0] + margin
                    && x.x < xs[1] - margin
                    && x.y > ys[0] + margin
                    && x.y < ys[1] - margin
            }
        };
        across && x.z > self.bottom + margin && x.z < self.top - margin
    }

    /// A uniformly random point of the cross-section's bounding rectangle, at a uniformly random
    /// height.
    fn draw(&self, rng: &mut ChaCha8Rng) -> Vec3 {
        let (x, y) = match self.section {
            Section::Circle { radius, .. } => ([-radius, radius], [-radius, radius]),
            Section::Rect { x, y } => (x, y),
        };
        Vec3::new(
            rng.random_range(x[0]..=x[1]),
            rng.random_range(y[0]..=y[1]),
            rng.random_range(self.bottom..=self.top),
        )
    }

    /// The same container scaled by `f` about the bottom's middle.
    fn scaled(&self, f: f64) -> Bounds {
        let section = match self.section {
            Section::Circle { radius, segments } => Section::Circle {
                radius: radius * f,
                segments,
            },
            Section::Rect { x, y } => Section::Rect {
                x: x.map(|v| v * f),
                y: y.map(|v| v * f),
            },
        };
        Bounds {
            section,
            bottom: self.bottom * f,
            top: self.top * f,
        }
    }

    /// The walls that make this container, in the order of [`Container`].
    fn walls(&self) -> Vec<Wall> {
        let mut walls = vec![
            Wall::plane(Vec3::new(0.0, 0.0, self.bottom), Vec3::z()),
            Wall::plane(Vec3::new(0.0, 0.0, self.top), -Vec3::z()),
        ];
        match self.section {
            Section::Circle { radius, segments } => {
                // Twice the height: the platens stay inside it as they move.
                let h = self.height();
                walls.push(Wall::cylinder(
                    Vec3::new(0.0, 0.0, self.bottom - 0.5 * h),
                    Vec3::z(),
                    radius,
                    2.0 * h,
                    segments,
                ));
            }
            Section::Rect { x, y } => {
                walls.push(Wall::plane(Vec3::new(x[0], 0.0, 0.0), Vec3::x()));
                walls.push(Wall::plane(Vec3::new(x[1], 0.0, 0.0), -Vec3::x()));
                walls.push(Wall::plane(Vec3::new(0.0, y[0], 0.0), Vec3::y()));
                walls.push(Wall::plane(Vec3::new(0.0, y[1], 0.0), -Vec3::y()));
            }
        }
        walls
    }

    /// Each wall's area, distance from the middle and share of the mean stress (its
    /// directions over 3, a platen's halved as it shares its direction with the other).
    fn geometry(&self) -> Vec<WallGeometry> {
        let h = self.height();
        let platen = || WallGeometry {
            area: self.area(),
            half: 0.5 * h,
            weight: 1.0 / 6.0,
        };
        let mut out = vec![platen(), platen()];
        match self.section {
            Section::Circle { radius, .. } => out.push(WallGeometry {
                area: self.perimeter() * h,
                half: radius,
                weight: 2.0 / 3.0,
            }),
            Section::Rect { x, y } => {
                for (side, across) in [(y[1] - y[0], x[1] - x[0]), (x[1] - x[0], y[1] - y[0])] {
                    for _ in 0..2 {
                        out.push(WallGeometry {
                            area: side * h,
                            half: 0.5 * across,
                            weight: 1.0 / 6.0,
                        });
                    }
                }
            }
        }
        out
    }

    /// "0.3000 m across and 0.6000 m high", or "0.3000 x 0.3000 m and ...".
    pub fn describe(&self) -> String {
        let across = match self.section {
            Section::Circle { radius, .. } => format!("{:.4} m across", 2.0 * radius),
            Section::Rect { x, y } => format!("{:.4} x {:.4} m", x[1] - x[0], y[1] - y[0]),
        };
        format!("{across} and {:.4} m high", self.height())
    }
}

/// The most particles a specimen may have.
pub const MAX_PARTICLES: usize = 1_000_000;

/// A uniformly random rotation (Shoemake's method).
fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let (a, b) = ((1.0 - u1).sqrt(), u1.sqrt());
    let (t2, t3) = (2.0 * PI * u2, 2.0 * PI * u3);
    UnitQuaternion::from_quaternion(Quaternion::new(
        b * t3.cos(),
        a * t2.sin(),
        a * t2.cos(),
        b * t3.sin(),
    ))
}

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
                 raise --size-min or shrink the container"
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
    w.dt = p.safety * w.critical_dt();
    Ok(w)
}

/// Density scaling for a quasi-static preparation: raises every free body's mass, and all its
/// moments by one factor, until its own critical steps for translation and for rotation
/// ([`World::critical_dts`]) are both the largest translational step of any body, the one of
/// the heaviest. Statics does not depend on inertia, and the step is then set by the big
/// bodies that carry the packing, not by the smallest or spikiest one. Angular velocities are
/// kept. [`restore_inertia`] undoes it.
pub fn scale_inertia(w: &mut World) {
    let dts = w.critical_dts();
    let target = (dts.iter())
        .map(|d| d.0)
        .filter(|t| t.is_finite())
        .fold(0.0, f64::max);
    for (b, (t, r)) in w.bodies.iter_mut().zip(dts) {
        if b.fixed {
            continue;
        }
        let rotation = square(target / r);
        b.mass *= square(target / t);
        b.moments *= rotation;
        b.ang_mom *= rotation;
    }
}

/// Gives every body its true mass and moments back (after [`scale_inertia`]), keeping its
/// velocity and angular velocity, and sets the time step from them.
pub fn restore_inertia(w: &mut World, p: &Params) {
    for i in 0..w.bodies.len() {
        let (mass, moments) = w.inertia_of(w.bodies[i].shape, w.bodies[i].scale);
        let b = &mut w.bodies[i];
        b.ang_mom *= moments.x / b.moments.x;
        b.mass = mass;
        b.moments = moments;
    }
    w.dt = p.safety * w.critical_dt();
}

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

/// The container of a specimen made by [`cloud`], as its walls are now; `None` when the walls
/// are not a pack container (bottom and top platens, then a cylinder or four side planes).
pub fn container(w: &World) -> Option<Bounds> {
    let plane = |k: usize, normal: Vec3| match w.walls.get(k).map(|x| &x.kind) {
        Some(WallKind::Plane { normal: n, offset }) if *n == normal => Some(*offset),
        _ => None,
    };
    let (bottom, top) = (plane(BOTTOM, Vec3::z())?, -plane(TOP, -Vec3::z())?);
    let section = match (w.walls.len(), w.walls.get(SIDE).map(|x| &x.kind)) {
        (
            3,
            Some(WallKind::Cylinder {
                radius, segments, ..
            }),
        ) => Section::Circle {
            radius: *radius,
            segments: *segments,
        },
        (6, _) => Section::Rect {
            x: [plane(SIDE, Vec3::x())?, -plane(SIDE + 1, -Vec3::x())?],
            y: [plane(SIDE + 2, Vec3::y())?, -plane(SIDE + 3, -Vec3::y())?],
        },
        _ => return None,
    };
    Some(Bounds {
        section,
        bottom,
        top,
    })
}

/// [`container`] of a world made by [`cloud`].
fn bounds(w: &World) -> Bounds {
    container(w).expect("the walls of a pack container")
}

/// Wall stresses (compression positive, Pa) and each wall's contact count, in the walls'
/// order: a plane's the normal force over its area, the cylinder's the radial force of its
/// contacts over its facets' area between the platens. `w` is made by [`cloud`].
pub fn wall_stresses(w: &World) -> (Vec<f64>, Vec<usize>) {
    let b = bounds(w);
    stresses_in(w, &b, &b.geometry())
}

/// [`wall_stresses`] in the container `b` of these walls' `geometry`.
fn stresses_in(w: &World, b: &Bounds, geometry: &[WallGeometry]) -> (Vec<f64>, Vec<usize>) {
    let mut counts = vec![0usize; geometry.len()];
    let mut radial = 0.0;
    let first = w.contacts.lower_bound(&(Partner::Wall(0), 0));
    for (&(partner, _), c) in w.contacts.iter().skip(first) {
        let Partner::Wall(k) = partner else { continue };
        let k = k as usize;
        if let Some(n) = counts.get_mut(k) {
            *n += 1;
        }
        if matches!(b.section, Section::Circle { .. }) && k == SIDE {
            let out = Vec3::new(c.point.x, c.point.y, 0.0);
            let len = out.norm();
            if len > 0.0 {
                let push = -(c.normal * c.normal_force + c.shear);
                radial += push.dot(&out) / len;
            }
        }
    }
    let stresses = (w.walls.iter().zip(geometry))
        .map(|(wall, g)| match &wall.kind {
            WallKind::Plane { normal, .. } => -wall.force.dot(normal) / g.area,
            _ => radial / g.area,
        })
        .collect();
    (stresses, counts)
}

/// The walls' speeds (inward positive, m/s, in the walls' order) under PFC's servo: each wall
/// `gain (p - sigma) A / (kn N dt)`, `N` its contacts (at least 1) and `A` its area, capped at
/// `max_strain_rate` times the wall's distance from the middle. With `common` (the integral
/// term, Pa), every wall moves at one strain rate instead, the smallest servo gain's acting on
/// the mean stress's error plus the integral: the specimen shrinks alike in every direction.
///
/// The gain is PFC's: it takes the wall's own contacts for the spring it pushes, but that spring
/// is in series with the whole packing, and a loose packing gives way as it rearranges: the
/// error decays over tens of thousands of steps instead of a few. The integral, the error
/// summed over `integral_steps`, makes up for that. It grows only while the walls are not at
/// their cap (no wind-up while the cloud is loose) and goes back to zero when the error changes
/// sign, so that it never drives the stress past the target.
fn servo(
    w: &World,
    p: &Params,
    geometry: &[WallGeometry],
    stresses: &[f64],
    counts: &[usize],
    common: Option<&mut f64>,
) -> Vec<f64> {
    let (kn, dt) = (w.material.kn, w.dt);
    let gain = |k: usize| p.gain * geometry[k].area / (kn * counts[k].max(1) as f64 * dt);
    if let Some(integral) = common {
        let error = p.pressure - mean_stress(geometry, stresses);
        let g = (0..geometry.len())
            .map(|k| gain(k) / geometry[k].half)
            .fold(f64::INFINITY, f64::min);
        // Particle-particle contacts come first in the list.
        let pairs = w.contacts.lower_bound(&(Partner::Wall(0), 0));
        let cap = if 2 * pairs < w.bodies.len() {
            p.loose_strain_rate.max(p.max_strain_rate)
        } else {
            p.max_strain_rate
        };
        if error * *integral < 0.0 {
            *integral = 0.0;
        }
        let wanted = g * (error + *integral);
        if p.integral_steps > 0 && wanted.abs() < cap {
            *integral += error / p.integral_steps as f64;
        }
        let rate = wanted.clamp(-cap, cap);
        geometry.iter().map(|g| rate * g.half).collect()
    } else {
        // A wall within half the tolerance rests: a servo that chases every fluctuation
        // keeps shaking the packing it should let settle.
        (0..geometry.len())
            .map(|k| {
                let cap = p.max_strain_rate * geometry[k].half;
                let error = p.pressure - stresses[k];
                if error.abs() <= 0.5 * p.tolerance * p.pressure {
                    0.0
                } else {
                    (gain(k) * error).clamp(-cap, cap)
                }
            })
            .collect()
    }
}

/// Moves the walls inward at `speeds` (see [`servo`]).
fn set_speeds(w: &mut World, speeds: &[f64]) {
    for (wall, &v) in w.walls.iter_mut().zip(speeds) {
        match &mut wall.kind {
            WallKind::Plane { normal, .. } => wall.velocity = *normal * v,
            WallKind::Cylinder { radial_rate, .. } => *radial_rate = -v,
            WallKind::Facets { .. } => {}
        }
    }
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

/// Solid volume of the bodies, m^3.
fn solid_volume(w: &World) -> f64 {
    w.bodies
        .iter()
        .map(|b| w.shapes[b.shape as usize].volume * cube(b.scale))
        .sum()
}

/// Porosity of the specimen (made by [`cloud`]) in its container.
pub fn porosity(w: &World) -> f64 {
    porosity_of(&bounds(w), solid_volume(w))
}

/// The container's core: the prism left when every wall moves `layer` inwards, as the
/// half-spaces `n . x <= d` that bound it and its volume; `None` when nothing is left. A
/// cylinder's core is a polygon of as many sides as its facets (in any orientation: the sides
/// only bound a region), its apothem `layer` shorter.
fn core(b: &Bounds, layer: f64) -> Option<(Vec<(Vec3, f64)>, f64)> {
    let (bottom, top) = (b.bottom + layer, b.top - layer);
    let mut planes = vec![(-Vec3::z(), -bottom), (Vec3::z(), top)];
    let section = match b.section {
        Section::Circle { radius, segments } => {
            let n = f64::from(segments);
            let apothem = radius * (PI / n).cos() - layer;
            planes.extend((0..segments).map(|k| {
                let a = 2.0 * PI * f64::from(k) / n;
                (Vec3::new(a.cos(), a.sin(), 0.0), apothem)
            }));
            (apothem > 0.0).then(|| Section::Circle {
                radius: apothem / (PI / n).cos(),
                segments,
            })
        }
        Section::Rect { x, y } => {
            let (x, y) = ([x[0] + layer, x[1] - layer], [y[0] + layer, y[1] - layer]);
            planes.extend([
                (-Vec3::x(), -x[0]),
                (Vec3::x(), x[1]),
                (-Vec3::y(), -y[0]),
                (Vec3::y(), y[1]),
            ]);
            (x[0] < x[1] && y[0] < y[1]).then_some(Section::Rect { x, y })
        }
    }?;
    let inset = Bounds {
        section,
        bottom,
        top,
    };
    (bottom < top).then(|| (planes, inset.area() * inset.height()))
}

/// Porosity of the container's core, `layer` in from every wall ([`core`]): the bodies' volume
/// inside it (each straddling body clipped exactly, [`clipped_volume`]) over its volume.
/// It leaves out the layer along the walls, where particles pack looser against a flat surface
/// (docs/pack.md has what it measures, small sample against specimen). `None` when the layer
/// leaves no core. `w` is made by [`cloud`].
pub fn core_porosity(w: &World, layer: f64) -> Option<f64> {
    let (planes, volume) = core(&bounds(w), layer)?;
    let solid: f64 = w
        .bodies
        .iter()
        .map(|body| {
            let s = &w.shapes[body.shape as usize];
            let posed = s.posed(&body.pos, &body.rot, body.scale);
            let (lo, hi) = (posed.lo, posed.hi);
            // Wholly beyond one plane (its box is), or wholly inside all of them.
            if (planes.iter()).any(|(n, d)| box_excess(&-n, -d, &lo, &hi) <= 0.0) {
                return 0.0;
            }
            if (planes.iter()).all(|(n, d)| box_excess(n, *d, &lo, &hi) <= 0.0) {
                return s.volume * cube(body.scale);
            }
            let faces: Vec<Vec<Vec3>> = (0..s.face_count())
                .map(|f| {
                    (s.face(f).iter())
                        .map(|&i| posed.vertex(s, i as usize))
                        .collect()
                })
                .collect();
            clipped_volume(&faces, &planes)
        })
        .sum();
    Some(1.0 - solid / volume)
}

/// [`porosity`] for bodies of `solid` volume in all.
fn porosity_of(b: &Bounds, solid: f64) -> f64 {
    1.0 - solid / (b.area() * b.height())
}

/// The mean of the wall stresses: `(sigma_x + sigma_y + sigma_z) / 3`, each direction's
/// stress the mean of its walls'.
fn mean_stress(geometry: &[WallGeometry], stresses: &[f64]) -> f64 {
    geometry
        .iter()
        .zip(stresses)
        .map(|(g, s)| g.weight * s)
        .sum()
}

/// Steps 3 and 4 on a cloud from [`cloud`]: compacts it and brings it to equilibrium;
/// `report` sees the status and the world every `every` steps. The walls are at rest at the
/// end.
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
    restore_inertia(w, p);
    Ok(())
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
    crate::dem::world::on_pool(|| {
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
            let speeds = servo(w, p, &geometry, &stresses, &counts, common);
            set_speeds(w, &speeds);
            w.step();
        }
    })
}

/// The void-ratio limits of the templates and sizes, and the preparation friction for a relative
/// density, found on a smaller sample (docs/pack.md, "Relative density").
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
        return Err(PackError::Bad(format!(
            "--calibration-scale must be in (0, 1], got {scale}"
        )));
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
/// preparation `friction`; `report` sees the friction and status.
fn compacted(
    templates: &[Shape],
    sample: &Params,
    friction: f64,
    every: u64,
    report: &mut (impl FnMut(f64, &Status) + Send),
) -> Result<(usize, f64), PackError> {
    let q = Params {
        prep_friction: friction,
        ..sample.clone()
    };
    let mut w = cloud(templates.to_vec(), &q)?;
    compact(&mut w, &q, every, |s, _| report(friction, s))?;
    let n = porosity(&w);
    Ok((w.bodies.len(), n / (1.0 - n)))
}

fn check_loose(loose_friction: f64) -> Result<(), PackError> {
    if loose_friction > 0.0 && loose_friction.is_finite() {
        Ok(())
    } else {
        Err(PackError::Bad(format!(
            "--loose-friction must be a positive friction coefficient, got {loose_friction}"
        )))
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
    mut report: impl FnMut(f64, &Status) + Send,
) -> Result<Limits, PackError> {
    limits_of(
        templates,
        &sample(p, scale)?,
        scale,
        loose_friction,
        every,
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
    report: &mut (impl FnMut(f64, &Status) + Send),
) -> Result<Limits, PackError> {
    check_loose(loose_friction)?;
    let (_, e_min) = compacted(templates, sample, 0.0, every, report)?;
    let (particles, e_max) = compacted(templates, sample, loose_friction, every, report)?;
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
    mut report: impl FnMut(f64, &Status) + Send,
) -> Result<Calibration, PackError> {
    if !(0.0..=1.0).contains(&relative_density) {
        return Err(PackError::Bad(format!(
            "--relative-density must be in [0, 1], got {relative_density}"
        )));
    }
    let sample = sample(p, scale)?;
    let limits = limits_of(
        templates,
        &sample,
        scale,
        loose_friction,
        every,
        &mut report,
    )?;
    let (e_min, e_max) = (limits.e_min, limits.e_max);
    let mut runs = vec![(0.0, e_min), (loose_friction, e_max)];
    let target = e_max - relative_density * (e_max - e_min);
    let (mut lo, mut hi) = (runs[0], runs[1]);
    for _ in 0..extra {
        let f = next_friction(lo, hi, target);
        let (_, e) = compacted(templates, &sample, f, every, &mut report)?;
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
/// that matters (I_P, session 16: 0.068 at friction 0.1, 0.073 at 0.067): each run measures
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
    mut report: impl FnMut(f64, &Status) + Send,
) -> Result<Refinement, PackError> {
    let (e_min, e_max) = limits;
    let target = e_max - calibration.relative_density * (e_max - e_min);
    let mut f = calibration.prep_friction;
    let mut done = Vec::with_capacity(runs);
    for _ in 0..runs {
        let (_, e) = compacted(templates, p, f, every, &mut report)?;
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

/// The deviatoric anisotropy a_c = (15/2) sqrt(3/2 d:d) of `count` unit normals whose `n n^T`
/// sum to `fabric` (d the deviator of their mean); 0 for none.
pub fn anisotropy(fabric: &nalgebra::Matrix3<f64>, count: usize) -> f64 {
    if count == 0 {
        return 0.0;
    }
    let f = fabric / count as f64;
    let d = f - nalgebra::Matrix3::identity() * (f.trace() / 3.0);
    7.5 * (1.5 * d.component_mul(&d).sum()).sqrt()
}

/// The summary of specimen `w` made with `p`.
pub fn summary(w: &World, p: &Params) -> Summary {
    let n = w.bodies.len();
    let inside = bounds(w);
    let size = |b: usize| {
        let body = &w.bodies[b];
        equivalent_diameter(w.shapes[body.shape as usize].volume) * body.scale
    };
    let mut ends = vec![0usize; n];
    let (mut pairs, mut fabric, mut max_overlap) = (0usize, nalgebra::Matrix3::zeros(), 0.0f64);
    for (&(partner, b), c) in &w.contacts {
        let smaller = match partner {
            Partner::Body(a) => {
                ends[a as usize] += 1;
                ends[b as usize] += 1;
                pairs += 1;
                fabric += c.normal * c.normal.transpose();
                size(a as usize).min(size(b as usize))
            }
            Partner::Wall(_) => size(b as usize),
        };
        max_overlap = max_overlap.max(c.depth / smaller);
    }
    let anisotropy = anisotropy(&fabric, pairs);
    let (n0, n1) = (
        ends.iter().filter(|&&e| e == 0).count(),
        ends.iter().filter(|&&e| e == 1).count(),
    );
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
    let mech = n as f64 - n0 as f64 - n1 as f64;
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
        coordination: if n > 0 {
            2.0 * pairs as f64 / n as f64
        } else {
            0.0
        },
        mechanical_coordination: if mech > 0.0 {
            (2.0 * pairs as f64 - n1 as f64) / mech
        } else {
            0.0
        },
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

    #[test]
    fn the_sample_curve_is_read_both_ways_in_the_square_root_of_the_friction() {
        // Session 16's Ab_1 sample: limits and two runs, out of order as they are run.
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
    fn random_rotations_are_unit_and_spread_over_all_directions() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut mean = Vec3::zeros();
        let n = 20000;
        for _ in 0..n {
            let q = random_rotation(&mut rng);
            assert!((q.norm() - 1.0).abs() < 1e-12);
            mean += q * Vec3::x();
        }
        // Uniform directions average to zero within a few 1 / sqrt(n).
        assert!((mean / n as f64).norm() < 0.03, "{mean:?}");
    }

    #[test]
    fn the_count_fills_the_container_at_the_porosity_in_equal_numbers() {
        let cube = Shape::from_mesh(&crate::mesh::cube(0.5)).unwrap();
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

    #[test]
    fn the_compaction_servo_integrates_only_below_its_cap_and_resets_when_the_error_turns() {
        let cube = Shape::from_mesh(&crate::mesh::cube(0.5)).unwrap();
        let p = Params {
            count: Some(4),
            diameter: 0.1,
            height: 0.2,
            size_min: 0.01,
            size_max: 0.02,
            ..Params::default()
        };
        let w = cloud(vec![cube], &p).unwrap();
        let geometry = bounds(&w).geometry();
        let half = geometry.iter().map(|g| g.half).collect::<Vec<_>>();
        // Nothing on the walls: one contact's gain, so the walls go at the loose cloud's cap
        // and nothing is integrated.
        let mut integral = 0.0;
        let v = servo(&w, &p, &geometry, &[0.0; 3], &[0; 3], Some(&mut integral));
        assert_eq!(integral, 0.0);
        for (v, h) in v.iter().zip(&half) {
            approx::assert_relative_eq!(*v, p.loose_strain_rate * h, max_relative = 1e-12);
        }
        // Near the target on stiff walls (a million contacts each): below the cap, so the error
        // adds up, a 2000th of it each step, and speeds the walls up by as much.
        let counts = [1_000_000; 3];
        let near = [0.99 * p.pressure; 3];
        let first = servo(&w, &p, &geometry, &near, &counts, Some(&mut integral));
        approx::assert_relative_eq!(integral, 0.01 * p.pressure / 2000.0, max_relative = 1e-12);
        let second = servo(&w, &p, &geometry, &near, &counts, Some(&mut integral));
        approx::assert_relative_eq!(
            second[SIDE] / first[SIDE],
            1.0 + 1.0 / 2000.0,
            max_relative = 1e-9
        );
        assert!(first[SIDE] > 0.0 && first[SIDE] < p.max_strain_rate * half[SIDE]);
        // Past the target: the integral starts again from zero at once, and the walls back out.
        let past = [1.01 * p.pressure; 3];
        let back = servo(&w, &p, &geometry, &past, &counts, Some(&mut integral));
        approx::assert_relative_eq!(integral, -0.01 * p.pressure / 2000.0, max_relative = 1e-12);
        assert!(back.iter().all(|&v| v < 0.0), "{back:?}");
        // Without integral action it never grows.
        let q = Params {
            integral_steps: 0,
            ..p.clone()
        };
        let mut integral = 0.0;
        servo(&w, &q, &geometry, &near, &counts, Some(&mut integral));
        assert_eq!(integral, 0.0);
    }

    #[test]
    fn inertia_scaling_gives_every_body_the_largest_step_and_restoring_gives_the_true_inertia() {
        // Spiky and flat templates, sizes 1:4: the step was set by the smallest, spikiest one.
        let shapes: Vec<Shape> = [6, 9, 14]
            .map(|faces| {
                let q = crate::polygen::Params {
                    faces,
                    ..Default::default()
                };
                let m = crate::polygen::generate(&q, 7, 0).unwrap().mesh;
                Shape::from_mesh(&m).unwrap()
            })
            .into();
        let p = Params {
            diameter: 0.2,
            height: 0.4,
            count: Some(30),
            inertia_scaling: false,
            ..Params::default()
        };
        let mut w = cloud(shapes, &p).unwrap();
        let true_dt = w.critical_dt();
        let largest = (w.critical_dts().iter()).map(|d| d.0).fold(0.0, f64::max);
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for b in w.bodies.iter_mut() {
            b.vel = Vec3::new(rng.random(), rng.random(), rng.random());
            b.ang_mom = Vec3::new(rng.random(), rng.random(), rng.random()) * b.moments.x;
        }
        let before: Vec<(Vec3, Vec3)> = w.bodies.iter().map(|b| (b.vel, b.omega())).collect();
        scale_inertia(&mut w);
        for (t, r) in w.critical_dts() {
            assert!((t - largest).abs() < 1e-12 * largest, "{t} {largest}");
            assert!((r - largest).abs() < 1e-12 * largest, "{r} {largest}");
        }
        assert!(largest > 4.0 * true_dt, "{largest} against {true_dt}");
        for (b, (v, omega)) in w.bodies.iter().zip(&before) {
            assert_eq!(b.vel, *v);
            assert!((b.omega() - omega).norm() < 1e-12 * omega.norm());
        }
        restore_inertia(&mut w, &p);
        assert_eq!(w.dt, p.safety * true_dt);
        for (b, (v, omega)) in w.bodies.iter().zip(&before) {
            let (mass, moments) = w.inertia_of(b.shape, b.scale);
            assert_eq!((b.mass, b.moments), (mass, moments));
            assert_eq!(b.vel, *v);
            assert!((b.omega() - omega).norm() < 1e-12 * omega.norm());
        }
    }

    #[test]
    fn core_porosity_counts_the_part_of_a_straddling_body_inside_the_core() {
        // One cube in a box 200 x 160 x 120 mm, its centre on the core's x-min side 30 mm in:
        // half of it is inside, upright or turned about z (a cube is symmetric about its
        // centre), and none of it when it lies wholly in the layer.
        let cube = Shape::from_mesh(&crate::mesh::cube(0.5)).unwrap();
        let p = Params {
            container: Container::Box,
            count: Some(1),
            width: 0.2,
            depth: 0.16,
            height: 0.12,
            size_min: 0.02,
            size_max: 0.02,
            ..Params::default()
        };
        let mut w = cloud(vec![cube], &p).unwrap();
        let b = bounds(&w);
        let Section::Rect { x, y } = b.section else {
            panic!("a box")
        };
        let layer = 0.03;
        let core =
            (x[1] - x[0] - 2.0 * layer) * (y[1] - y[0] - 2.0 * layer) * (b.height() - 2.0 * layer);
        let side = w.bodies[0].scale;
        let middle = Vec3::new(x[0] + layer, 0.5 * (y[0] + y[1]), 0.5 * (b.bottom + b.top));
        for turn in [0.0, 0.3, PI / 4.0] {
            w.bodies[0].pos = middle;
            w.bodies[0].rot = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), turn);
            let expected = 1.0 - 0.5 * crate::math::cube(side) / core;
            let got = core_porosity(&w, layer).unwrap();
            assert!(
                (got - expected).abs() < 1e-12,
                "turn {turn}: {got} {expected}"
            );
        }
        w.bodies[0].pos.x = x[0] + 0.4 * layer;
        assert_eq!(core_porosity(&w, layer), Some(1.0));
        // No layer and the cube inside: the container's porosity.
        w.bodies[0].pos = middle + Vec3::x() * 0.05;
        let whole = core_porosity(&w, 0.0).unwrap();
        assert!(
            (whole - porosity(&w)).abs() < 1e-12,
            "{whole} {}",
            porosity(&w)
        );
        // A layer that leaves nothing.
        assert_eq!(core_porosity(&w, 0.061), None);
        // A cylinder's core without a layer is its facet polygon, as the porosity's.
        let q = Params {
            container: Container::Cylinder,
            diameter: 0.1,
            ..p.clone()
        };
        let c = cloud(w.shapes.clone(), &q).unwrap();
        let whole = core_porosity(&c, 0.0).unwrap();
        assert!(
            (whole - porosity(&c)).abs() < 1e-12,
            "{whole} {}",
            porosity(&c)
        );
    }

    #[test]
    fn anisotropy_is_7_5_for_aligned_normals_and_7_5_over_root_n_for_random_ones() {
        let z = Vec3::z();
        assert!((anisotropy(&(z * z.transpose() * 10.0), 10) - 7.5).abs() < 1e-12);
        // Along the three axes alike: isotropic.
        let axes = Vec3::x() * Vec3::x().transpose()
            + Vec3::y() * Vec3::y().transpose()
            + z * z.transpose();
        assert!(anisotropy(&axes, 3) < 1e-12);
        // Isotropic random normals: the root mean square is Summary::anisotropy_noise's.
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let n = 500;
        let trials = 400;
        let mut sum2 = 0.0;
        for _ in 0..trials {
            let mut fabric = nalgebra::Matrix3::zeros();
            for _ in 0..n {
                let v = random_rotation(&mut rng) * z;
                fabric += v * v.transpose();
            }
            sum2 += crate::math::square(anisotropy(&fabric, n));
        }
        let rms = (sum2 / trials as f64).sqrt();
        let expected = 7.5 / (n as f64).sqrt();
        assert!(
            (rms / expected - 1.0).abs() < 0.05,
            "{rms} against {expected}"
        );
    }
}
