//! The DEM world: bodies, walls, contacts, and one time step.
//!
//! Physics (the paper's, PFC-like):
//! - contact geometry from the overlap polyhedron ([`crate::dem::collision::overlap`]): normal `n` from A to B,
//!   depth `delta`, point at the overlap centroid; one contact per touching pair;
//! - linear law: `F_n = kn delta` (no tension); incremental shear spring `ks` on the relative
//!   tangential velocity at the contact point, the stored shear force carried onto the new
//!   tangent plane every step (direction projected, magnitude kept), Coulomb limit `mu F_n`;
//! - local non-viscous damping (PFC): `F_i -= alpha |F_i| sign(v_i)` per component, moments
//!   likewise;
//! - walls move first in a step, by the velocities set before it, then the contacts see them
//!   there (a wall's velocity set between steps acts on this step's forces);
//! - time integration: leapfrog (central differences) for translation; for rotation the
//!   world-frame angular momentum takes the torque kick, and the orientation advances by the
//!   symplectic splitting of the free rigid rotor into rotations about the principal axes
//!   (Dullweber, Leimkuhler, McLachlan 1997): |L| is exact, the energy error stays bounded, and
//!   the intermediate-axis (Dzhanibekov) flip comes out right.
//!
//! Determinism: contact forces are computed in parallel into a list in pair order; each body
//! (in parallel) adds its own in that order, and sums over bodies are taken in body order;
//! contacts are listed by key ([`Contacts`]). Same bytes for any thread count.
//!
//! Energy audit: kinetic + elastic (normal and shear springs) + friction and damping
//! dissipation - work of gravity - work of moving walls is constant; [`Energy::balance`].

mod step;

use crate::dem::collision::broad::Broad;
use crate::dem::collision::gaps::Separations;
use crate::dem::collision::kept::Structure;
use crate::dem::contacts::{ContactKey, Contacts, Partner};
use crate::dem::energy::Energy;
use crate::dem::law::{flat_potential, Contact, Material};
use crate::dem::parallel::filter_map_maybe_par;
use crate::dem::shape::{Posed, Remade, Shape};
use crate::dem::wall::{FacetGrid, Wall, WallKind};
use crate::math::{cube, pow5, Vec3};
use nalgebra::UnitQuaternion;
use step::Buffers;

/// A body whose motion the integrator has lost ([`World::runaway`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("body {body} {what}")]
pub struct Runaway {
    pub body: usize,
    pub what: String,
}

/// Why a world has no time step ([`World::time_step`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TimeStepError {
    #[error("no free body or membrane moves, so nothing sets a time step (give one)")]
    Nothing,
    #[error("the critical time step is {critical:e} s: the contact stiffness {stiffness:e} N/m against the lightest free body's {lightest:e} kg (and its moments) is out of the range a step can resolve")]
    OutOfRange {
        critical: f64,
        stiffness: f64,
        lightest: f64,
    },
}

/// A rigid body: a scaled shape, its pose and motion. `ang_mom` is the angular momentum about the
/// centroid in world axes; `rot` turns the shape's principal frame into world axes.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    pub shape: u32,
    pub scale: f64,
    pub pos: Vec3,
    pub rot: UnitQuaternion<f64>,
    pub vel: Vec3,
    pub ang_mom: Vec3,
    /// A fixed body does not move (infinite mass in contacts).
    pub fixed: bool,
    pub mass: f64,
    /// Principal moments of inertia, kg m^2.
    pub moments: Vec3,
}

impl Body {
    /// Angular velocity in world axes.
    pub fn omega(&self) -> Vec3 {
        let pi = self.rot.inverse_transform_vector(&self.ang_mom);
        self.rot.transform_vector(&pi.component_div(&self.moments))
    }

    /// Kinetic energy, translation plus rotation.
    pub fn kinetic_energy(&self) -> f64 {
        if self.fixed {
            return 0.0;
        }
        0.5 * self.mass * self.vel.norm_squared() + 0.5 * self.ang_mom.dot(&self.omega())
    }

    /// Velocity of the material point at world position `p`.
    pub fn velocity_at(&self, p: &Vec3) -> Vec3 {
        self.velocity_with(&self.omega(), p)
    }

    /// The angular velocity `omega` ([`Body::omega`], as computed already) the body turns
    /// at: none for a fixed body.
    fn spin_with(&self, omega: &Vec3) -> Vec3 {
        if self.fixed {
            Vec3::zeros()
        } else {
            *omega
        }
    }

    /// [`Body::velocity_at`] with the body's angular velocity `omega` ([`Body::omega`]) as
    /// computed already.
    fn velocity_with(&self, omega: &Vec3, p: &Vec3) -> Vec3 {
        if self.fixed {
            return Vec3::zeros();
        }
        self.vel + omega.cross(&(p - self.pos))
    }
}

/// The simulated world.
#[derive(Clone, Debug)]
pub struct World {
    pub shapes: Vec<Shape>,
    pub bodies: Vec<Body>,
    pub walls: Vec<Wall>,
    pub material: Material,
    pub gravity: Vec3,
    pub dt: f64,
    pub time: f64,
    pub step: u64,
    pub contacts: Contacts,
    pub energy: Energy,
    /// Unbalanced-force ratio of the last step: the mean over free bodies of the net force
    /// (gravity and contacts, before damping) over the mean contact force; infinite with no
    /// contacts. Derived, not part of the state.
    pub unbalanced: f64,
    /// For body pairs whose boxes overlapped last step while the bodies did not: the direction
    /// that proved the gap and the supports it ended on, where this step's proof starts. Only
    /// speed depends on it (the proof is exact beyond round-off, see `overlap::apart`), so it
    /// is not part of the state.
    separations: Separations,
    /// Scratch of the broad phase, kept between steps: the posed bodies (for their buffers)
    /// and the kept list of pairs. Not part of the state (only speed depends on it).
    posed: Vec<Posed>,
    /// A spare buffer for the kept structures' words when [`Contacts::keep`] compacts them.
    kept_buffer: Vec<u32>,
    /// Per body pair in contact whose kept structure stopped holding: that structure, and the
    /// pair's shapes then, tried before a structure is looked for ([`overlap_kept_or`]). Only
    /// speed depends on it, so it is not part of the state.
    alternates: Alternates,
    /// The facet sets ([`crate::dem::wall::Wall::touch_kept`]) of bodies whose boxes reached
    /// a facet wall last step without touching it, by wall and body: a body that comes near
    /// the membrane keeps its set until it touches (made anew each step, they were a sixth of
    /// the membrane's sets). Only speed depends on them, so they are not part of the state.
    near_sets: NearSets,
    /// Each wall's [`FacetGrid`] (`None` for other walls), kept while it fits the nodes. Only
    /// speed depends on it.
    grids: Vec<Option<FacetGrid>>,
    broad: Broad,
    buffers: Buffers,
    /// Whether contacts keep their overlap's structure for the next step ([`crate::dem::collision::kept`]).
    /// Only speed depends on it; off, every contact's structure is found again each step.
    pub keep_structures: bool,
    /// Wall-clock seconds spent in each part of [`World::step`] so far (not part of the state).
    pub times: StepTimes,
}

/// Where a step's time goes, wall-clock seconds summed over steps. Timing only reads the clock:
/// results do not depend on it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepTimes {
    /// Posing the bodies (world vertices, planes, boxes) and the sweep for box-overlapping pairs.
    pub broad: f64,
    /// Gap proofs and overlap polyhedra of body pairs, and their contact forces, with the
    /// body-wall contacts beside them (the two run side by side).
    pub narrow: f64,
    /// Each body's contacts listed and its forces summed, damping, kick, drift and rotation,
    /// with the contact list, the walls' loads and the energy sums made beside them (the two
    /// run side by side).
    pub integration: f64,
}

impl StepTimes {
    pub fn total(&self) -> f64 {
        self.broad + self.narrow + self.integration
    }
}

/// [`World::near_sets`]: by (wall, body), the facet set's words.
pub(crate) type NearSets = std::collections::HashMap<(u32, u32), Vec<u32>>;

/// [`World::alternates`]: by body pair, the shapes and the structure.
type Alternates = std::collections::HashMap<(u32, u32), ([u32; 2], Structure)>;

impl World {
    /// An empty world with a material and gravity; time step to be set (see `critical_dt`).
    pub fn new(material: Material, gravity: Vec3) -> World {
        World {
            shapes: Vec::new(),
            bodies: Vec::new(),
            walls: Vec::new(),
            material,
            gravity,
            dt: 0.0,
            time: 0.0,
            step: 0,
            contacts: Contacts::new(),
            energy: Energy::default(),
            unbalanced: f64::INFINITY,
            separations: Separations::default(),
            posed: Vec::new(),
            kept_buffer: Vec::new(),
            alternates: Alternates::new(),
            near_sets: NearSets::new(),
            grids: Vec::new(),
            broad: Broad::default(),
            buffers: Buffers::default(),
            keep_structures: true,
            times: StepTimes::default(),
        }
    }

    /// Adds a shape template; returns its index.
    pub fn add_shape(&mut self, shape: Shape) -> u32 {
        self.shapes.push(shape);
        self.shapes.len() as u32 - 1
    }

    /// Adds a body of shape `shape` scaled by `scale`, centroid at `pos`; returns its index.
    pub fn add_body(
        &mut self,
        shape: u32,
        scale: f64,
        pos: Vec3,
        rot: UnitQuaternion<f64>,
    ) -> usize {
        let (mass, moments) = self.inertia_of(shape, scale);
        let body = Body {
            shape,
            scale,
            pos,
            rot,
            vel: Vec3::zeros(),
            ang_mom: Vec3::zeros(),
            fixed: false,
            mass,
            moments,
        };
        self.bodies.push(body);
        self.bodies.len() - 1
    }

    /// Abrades every shape `levels` times in place ([`Shape::abraded`]); see [`World::reshape`].
    pub fn abrade(&mut self, levels: u32) -> Result<(), String> {
        if levels == 0 {
            return Ok(());
        }
        self.reshape(|s| s.abraded(levels))
    }

    /// Cuts every shape to `budget` vertices in place ([`Shape::simplified`]; shapes within
    /// the budget stay as they are); see [`World::reshape`].
    pub fn simplify(&mut self, budget: usize) -> Result<(), String> {
        self.reshape(|s| {
            if s.vertices.len() <= budget {
                Ok((s.clone(), Vec3::zeros(), UnitQuaternion::identity()))
            } else {
                s.simplified(budget)
            }
        })
    }

    /// Replaces every shape by `remake(shape)`, a shape inside it: each body keeps where its
    /// material was (so bodies only shrink), its velocity and its angular velocity, with the new
    /// mass and moments. Contacts are dropped (their depths and springs belonged to the old
    /// surfaces; the next step finds the new ones) and the energy audit starts again from the
    /// new kinetic energy.
    fn reshape(
        &mut self,
        remake: impl Fn(&Shape) -> Result<Remade, String> + Sync + Send,
    ) -> Result<(), String> {
        let remade = filter_map_maybe_par(&self.shapes, true, |s| Some(remake(s)));
        let mut moved = Vec::with_capacity(remade.len());
        for (s, r) in self.shapes.iter_mut().zip(remade) {
            let (shape, offset, turn) = r?;
            *s = shape;
            moved.push((offset, turn));
        }
        for i in 0..self.bodies.len() {
            let (shape, scale) = (self.bodies[i].shape, self.bodies[i].scale);
            let (mass, moments) = self.inertia_of(shape, scale);
            let b = &mut self.bodies[i];
            let omega = b.omega();
            let (offset, turn) = moved[b.shape as usize];
            b.pos += b.rot * (offset * b.scale);
            b.rot *= turn;
            b.mass = mass;
            b.moments = moments;
            let body_omega = b.rot.inverse_transform_vector(&omega);
            b.ang_mom = b
                .rot
                .transform_vector(&body_omega.component_mul(&b.moments));
        }
        self.contacts.clear();
        self.alternates.clear();
        self.near_sets.clear();
        self.separations = Separations::default();
        self.energy = Energy {
            kinetic: self.bodies.iter().map(Body::kinetic_energy).sum(),
            ..Energy::default()
        };
        Ok(())
    }

    /// Renumbers the bodies along a Morton (Z-order) curve through their centroids, so that
    /// bodies near each other in space are near each other in the lists a step walks (ids in
    /// the order a scene was built, or at random, make every pair's second body a cache miss;
    /// molecular dynamics codes sort their atoms the same way). Each body keeps its state under
    /// its new id; contacts follow their bodies (a body pair whose ids change order swaps its
    /// roles: the normal, from the lower id to the higher, and the shear force, on the higher,
    /// change sign). Only numbering and summation order change, not the scene; derived data
    /// (kept structures, gap proofs, the broad phase's list) start again. Returns the new id of
    /// each old one. Ties (bodies in one cell of the curve's 2^21 per axis) keep their order,
    /// so renumbering an ordered scene changes nothing.
    pub fn renumber_along_space(&mut self) -> Vec<u32> {
        let n = self.bodies.len();
        let (lo, hi) =
            crate::math::bounding_box(&self.bodies.iter().map(|b| b.pos).collect::<Vec<_>>())
                .unwrap_or((Vec3::zeros(), Vec3::zeros()));
        let cells = f64::from((1u32 << 21) - 1);
        let code = |p: &Vec3| {
            let mut key = 0u64;
            for k in 0..3 {
                let span = hi[k] - lo[k];
                let q = if span > 0.0 {
                    ((p[k] - lo[k]) / span * cells).round().clamp(0.0, cells) as u64
                } else {
                    0
                };
                key |= spread_bits(q) << k;
            }
            key
        };
        let mut order: Vec<u32> = (0..n as u32).collect();
        let codes: Vec<u64> = self.bodies.iter().map(|b| code(&b.pos)).collect();
        order.sort_by_key(|&i| (codes[i as usize], i));
        let mut new_id = vec![0u32; n];
        for (k, &i) in order.iter().enumerate() {
            new_id[i as usize] = k as u32;
        }
        let old = std::mem::take(&mut self.bodies);
        self.bodies = order.iter().map(|&i| old[i as usize].clone()).collect();
        let mut moved: Vec<(ContactKey, Contact)> = self
            .contacts
            .iter()
            .map(|(&(partner, b), c)| {
                let b = new_id[b as usize];
                match partner {
                    Partner::Wall(w) => ((Partner::Wall(w), b), c.clone()),
                    Partner::Body(a) => {
                        let a = new_id[a as usize];
                        if a < b {
                            ((Partner::Body(a), b), c.clone())
                        } else {
                            let flipped = Contact {
                                normal: -c.normal,
                                shear: -c.shear,
                                ..c.clone()
                            };
                            ((Partner::Body(b), a), flipped)
                        }
                    }
                }
            })
            .collect();
        moved.sort_by_key(|m| m.0);
        self.contacts = Contacts::from_sorted(&moved, false, |m| m.0, |m| m.1.clone());
        self.separations = Separations::default();
        self.broad = Broad::default();
        self.posed.clear();
        self.kept_buffer.clear();
        self.alternates.clear();
        self.near_sets.clear();
        new_id
    }

    /// Replaces the contact stiffnesses, carrying the contacts over at the same depths and
    /// shear displacements: forces scale by the ratios, and each contact's stored energy starts
    /// again from `Fn^2 / 2kn` (what a new contact gets). The work a contact has stored under
    /// the old stiffness is path-dependent (the law is not conservative off flat contacts), so
    /// scaling it would scale its drift too: from kn = 5e3 to 1e8 N/m that made a settled bed's
    /// elastic energy -234 J. The energy a change adds or removes is not work done by anything
    /// in the audit, so `balance()` moves by it. Set a new time step afterwards.
    pub fn set_stiffness(&mut self, kn: f64, ks: f64) {
        let (rn, rs) = (kn / self.material.kn, ks / self.material.ks);
        for c in self.contacts.values_mut() {
            c.normal_force *= rn;
            c.potential = flat_potential(c.normal_force, c.depth);
            if rs.is_finite() {
                c.shear *= rs;
            }
        }
        self.material.kn = kn;
        self.material.ks = ks;
        self.energy.elastic = self
            .contacts
            .values()
            .map(|c| c.elastic_energy(&self.material))
            .sum();
    }

    /// The critical time step of the stiffest oscillator: min over free bodies of
    /// `sqrt(m / k)` (translation) and `1 / omega_r` (rotation), `k = max(kn, ks)`.
    /// `omega_r` is the fastest rotation one spring can drive: a spring of stiffness `k` at a
    /// point `r` of the body, along any direction, has `omega^2 = k (r x n) . I^-1 (r x n)`; its
    /// largest over `n` is the top eigenvalue of `k I^-1/2 (|r|^2 - r r^T) I^-1/2`, and over
    /// the hull (that eigenvalue is convex in `r`) it is largest at a vertex (see
    /// [`Shape::rotation_rate`]). For a shape of equal moments that is `k r^2 / I`, `r` the
    /// bounding radius; an elongated shape, whose smallest moment is about its long axis, gets
    /// a longer step than `k r^2 / I_min` would give it. Multiply by a safety factor below 1 for
    /// `dt`.
    pub fn critical_dt(&self) -> f64 {
        (self.critical_dts().iter())
            .map(|&(t, r)| t.min(r))
            .fold(self.membranes_critical_dt(), f64::min)
    }

    /// The first body whose state is not finite, or that moves more than its own bounding
    /// radius in one step (`|v| dt > r`: no contact can resolve that, so the integration has
    /// blown up: a time step above the critical one, a body started deep in a wall, forces out
    /// of range); `None` while every body is sound.
    pub fn runaway(&self) -> Option<Runaway> {
        self.bodies.iter().enumerate().find_map(|(i, b)| {
            let finite = b
                .pos
                .iter()
                .chain(b.vel.iter())
                .chain(b.ang_mom.iter())
                .all(|x| x.is_finite())
                && b.rot.coords.iter().all(|x| x.is_finite());
            if !finite {
                return Some(Runaway {
                    body: i,
                    what: "has a position, orientation or velocity that is not a finite number"
                        .into(),
                });
            }
            let r = self.bounding_radius(b);
            if b.vel.norm_squared() * (self.dt * self.dt) <= r * r {
                return None;
            }
            let travel = b.vel.norm() * self.dt;
            Some(Runaway {
                body: i,
                what: format!(
                    "moves {travel:.3e} m in a step, more than its size {r:.3e} m (at {:.3e} m/s)",
                    b.vel.norm()
                ),
            })
        })
    }

    /// The contact whose overlap is the largest share of its smaller body's bounding radius
    /// (a wall contact: of its body's): `(key, depth / radius)`, or `None` without contacts. A
    /// penalty contact of more than a small share of a radius is far outside the linear law's
    /// range: bodies started inside each other are flung apart by it.
    pub fn deepest_overlap(&self) -> Option<(ContactKey, f64)> {
        let radius = |b: u32| self.bounding_radius(&self.bodies[b as usize]);
        (self.contacts.iter())
            .map(|(&(partner, b), c)| {
                let r = match partner {
                    Partner::Body(a) => radius(a).min(radius(b)),
                    Partner::Wall(_) => radius(b),
                };
                ((partner, b), c.depth / r)
            })
            // The first of equal depths.
            .reduce(|best, next| if next.1 > best.1 { next } else { best })
    }

    /// The radius of the sphere about body `b`'s centre of mass that holds it.
    pub fn bounding_radius(&self, b: &Body) -> f64 {
        self.shapes[b.shape as usize].radius * b.scale
    }

    /// The time step `safety x` [`World::critical_dt`], or why there is none: a critical step
    /// that is zero, not a number or below the smallest normal float (stiffness or inertia
    /// out of range: `kn = 1e308` overflows the rotation rate), or infinite (no free body or
    /// membrane moves).
    pub fn time_step(&self, safety: f64) -> Result<f64, TimeStepError> {
        let critical = self.critical_dt();
        let dt = safety * critical;
        if critical.is_infinite() {
            return Err(TimeStepError::Nothing);
        }
        if !(dt.is_finite() && dt >= f64::MIN_POSITIVE) {
            let k = self.material.kn.max(self.material.ks);
            let lightest = (self.bodies.iter())
                .filter(|b| !b.fixed)
                .map(|b| b.mass)
                .fold(f64::INFINITY, f64::min);
            return Err(TimeStepError::OutOfRange {
                critical,
                stiffness: k,
                lightest,
            });
        }
        Ok(dt)
    }

    /// The smallest critical step of the membranes' nodes ([`crate::dem::membrane::Membrane::critical_dt`]), infinite
    /// without membranes.
    pub fn membranes_critical_dt(&self) -> f64 {
        (self.walls.iter())
            .filter_map(|w| match (&w.kind, &w.membrane) {
                (WallKind::Facets { triangles, .. }, Some(m)) => Some(m.critical_dt(triangles)),
                _ => None,
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Each body's own critical steps, for translation and for rotation (see
    /// [`World::critical_dt`], their smallest; infinite for a fixed body). They come from the
    /// body's `mass` and `moments`, so a body whose inertia was scaled (all three moments by
    /// one factor) gets its own.
    pub fn critical_dts(&self) -> Vec<(f64, f64)> {
        let k = self.material.kn.max(self.material.ks);
        let rates: Vec<f64> = self.shapes.iter().map(Shape::rotation_rate).collect();
        (self.bodies.iter())
            .map(|b| {
                if b.fixed {
                    return (f64::INFINITY, f64::INFINITY);
                }
                // Lengths scale by s and the moments by c: the rate by s^2 / c.
                let s = &self.shapes[b.shape as usize];
                let rotation =
                    rates[b.shape as usize] * b.scale * b.scale * s.moments.x / b.moments.x;
                ((b.mass / k).sqrt(), 1.0 / (k * rotation).sqrt())
            })
            .collect()
    }

    /// The mass and principal moments of a body of `shape` at `scale`, at the material's
    /// density.
    pub fn inertia_of(&self, shape: u32, scale: f64) -> (f64, Vec3) {
        let s = &self.shapes[shape as usize];
        let rho = self.material.density;
        (
            rho * s.volume * cube(scale),
            s.moments * (rho * pow5(scale)),
        )
    }

    /// How many times the broad phase has swept all boxes since this world was made or read
    /// (the other steps filtered its kept list of pairs; see [`crate::dem::collision::broad`]).
    pub fn broad_sweeps(&self) -> u64 {
        self.broad.sweeps
    }
}

/// The 21 low bits of `x` spread to every third bit (bit `k` to bit `3 k`): one axis of a
/// Morton code.
fn spread_bits(x: u64) -> u64 {
    (0..21).fold(0, |acc, k| acc | ((x >> k) & 1) << (3 * k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::collision::gaps::Placed;
    use crate::dem::integrate::{free_rotation, free_rotations, half_angle_sin_cos};
    use crate::dem::parallel::{on_pool, PARALLEL_MIN_BODIES};
    use crate::geometry::mesh::{cube, cuboid};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// The splitting written out per axis turns as nalgebra's general products do (to
    /// round-off), for turns per step from 1e-9 rad to past the series' range; the series
    /// agree with libm to an ulp or two.
    #[test]
    fn free_rotation_per_axis_matches_general_quaternion_products() {
        fn general(rot: &mut UnitQuaternion<f64>, l: &Vec3, moments: &Vec3, dt: f64) {
            let mut pi = rot.inverse_transform_vector(l);
            for (axis, h) in [(0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)] {
                let theta = pi[axis] / moments[axis] * h * dt;
                let e = nalgebra::Unit::new_unchecked(Vec3::ith(axis, 1.0));
                let r = UnitQuaternion::from_axis_angle(&e, theta);
                pi = r.inverse_transform_vector(&pi);
                *rot *= r;
            }
            *rot = UnitQuaternion::new_normalize(*rot.quaternion());
        }
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for k in 0..2000 {
            let q = random_rotation(&mut rng);
            let moments = Vec3::new(1.0, 2.0, 3.5) * (1.0 + rng.random::<f64>());
            let spin = 10f64.powf(-9.0 + 9.0 * rng.random::<f64>());
            let l = random_rotation(&mut rng).transform_vector(&moments) * spin;
            let (mut a, mut b) = (q, q);
            free_rotation(&mut a, &l, &moments, 0.1);
            general(&mut b, &l, &moments, 0.1);
            assert!(a.angle_to(&b) < 1e-14, "case {k}: {:e}", a.angle_to(&b));
            assert!((a.quaternion().norm() - 1.0).abs() < 1e-15);
        }
        // Four at a time, fixed bodies left alone: the same numbers as one at a time.
        let mut w = heap();
        for (k, b) in w.bodies.iter_mut().enumerate() {
            b.ang_mom = random_rotation(&mut rng).transform_vector(&b.moments) * 30.0;
            b.fixed = k % 7 == 3;
        }
        let mut one = w.bodies.clone();
        // Eleven: the last group of four is short.
        free_rotations(&mut w.bodies[..11], 1e-3);
        for (k, (a, b)) in one.iter_mut().zip(&w.bodies).enumerate() {
            let before = a.rot;
            if !a.fixed && k < 11 {
                free_rotation(&mut a.rot, &a.ang_mom, &a.moments, 1e-3);
                assert_ne!(a.rot, before);
            }
            assert_eq!(a.rot, b.rot);
        }
        for k in 0..1000 {
            let x = (rng.random::<f64>() - 0.5) * 2e-2 * (k as f64 / 1000.0);
            let (s, c) = half_angle_sin_cos(x);
            assert!(
                (s - x.sin()).abs() <= 2.0 * f64::EPSILON * x.abs(),
                "sin {x}"
            );
            assert!((c - x.cos()).abs() <= 2.0 * f64::EPSILON, "cos {x}");
        }
    }

    fn random_rotation(rng: &mut ChaCha8Rng) -> UnitQuaternion<f64> {
        let axis = Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0));
        UnitQuaternion::from_scaled_axis(axis * rng.random_range(0.0..3.0))
    }

    /// Twelve cubes and bars dropped in a column into a narrow box, numbered from the top
    /// down (so the ids are not in space order), and settled with damping: lasting contacts
    /// between bodies and with the walls.
    fn heap() -> World {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let material = Material {
            kn: 1e6,
            ks: 5e5,
            ..Material::default()
        };
        let mut w = World::new(material, Vec3::new(0.0, 0.0, -9.81));
        let c = w.add_shape(Shape::from_mesh(&cube(0.5)).unwrap());
        let bar = w.add_shape(Shape::from_mesh(&cuboid(Vec3::new(1.0, 0.5, 0.5))).unwrap());
        for k in (0..12).rev() {
            let jitter = Vec3::from_fn(|_, _| rng.random_range(-0.003..0.003));
            let at = Vec3::new(0.02, 0.02, 0.015 + 0.03 * k as f64) + jitter;
            w.add_body([c, bar][k % 2], 0.02, at, random_rotation(&mut rng));
        }
        // A box 40 mm across around them: they must stack.
        open_box(&mut w, 0.04);
        for _ in 0..60_000 {
            w.step();
        }
        w
    }

    /// 125 cubes of 20 mm in a block on the floor of a box, each pressed 0.1 mm into its
    /// neighbours and slightly turned: contacts from the first step, and enough bodies for a
    /// step to run on the pool (and keep its threads [`Awake`]).
    fn block() -> World {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut w = World::new(Material::default(), Vec3::new(0.0, 0.0, -9.81));
        let c = w.add_shape(Shape::from_mesh(&cube(0.5)).unwrap());
        for k in 0..125 {
            let cell = Vec3::new((k % 5) as f64, (k / 5 % 5) as f64, (k / 25) as f64);
            let tilt = Vec3::from_fn(|_, _| rng.random_range(-0.002..0.002));
            let at = Vec3::repeat(0.00995) + cell * 0.0199;
            w.add_body(c, 0.02, at, UnitQuaternion::new(tilt));
        }
        open_box(&mut w, 0.1);
        w
    }

    /// Walls of an open box `side` across from the origin (a floor at z = 0 and four sides),
    /// and the time step 0.2 x critical.
    fn open_box(w: &mut World, side: f64) {
        use crate::dem::wall::Wall;
        w.walls.push(Wall::plane(Vec3::zeros(), Vec3::z()));
        for (point, normal) in [(0.0, 1.0), (side, -1.0)] {
            w.walls
                .push(Wall::plane(Vec3::repeat(point), Vec3::x() * normal));
            w.walls
                .push(Wall::plane(Vec3::repeat(point), Vec3::y() * normal));
        }
        w.dt = 0.2 * w.critical_dt();
    }

    /// The state of `w` after `steps` steps, as written.
    fn stepped(mut w: World, steps: usize) -> Vec<u8> {
        on_pool(|| (0..steps).for_each(|_| w.step()));
        let mut out = Vec::new();
        crate::dem::io::state::write_world(&w, &mut out).unwrap();
        out
    }

    /// Guards [`Awake`] and [`Buffers`]: two worlds stepped side by side on one pool of two
    /// threads, where each stepping thread's idle moments can run the other world's keep-awake
    /// loop (which must then end on its own), finish, and each ends as it does stepped alone
    /// on two threads, on one, and on two and then one.
    #[test]
    fn worlds_stepped_side_by_side_or_moved_between_pools_end_as_each_alone() {
        let w = block();
        assert!(
            w.bodies.len() >= PARALLEL_MIN_BODIES,
            "the block runs on the pool"
        );
        let pool = |n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .unwrap()
        };
        let alone = pool(1).install(|| stepped(w.clone(), 300));
        let (one, other) =
            pool(2).install(|| rayon::join(|| stepped(w.clone(), 300), || stepped(w.clone(), 300)));
        let two = pool(2).install(|| stepped(w.clone(), 300));
        // One world moved between pools halfway, its kept buffers with it (`Buffers`: one
        // pool per thread, three slots and then two).
        let mut moved = w.clone();
        pool(2).install(|| on_pool(|| (0..150).for_each(|_| moved.step())));
        let moved = pool(1).install(|| stepped(moved, 150));
        assert!(alone != stepped(w.clone(), 0), "the bodies moved");
        assert!(one == alone && other == alone && two == alone && moved == alone);
        let mut touched = w;
        touched.step();
        assert!(
            touched.contacts.len() > 300,
            "{} contacts",
            touched.contacts.len()
        );
    }

    #[test]
    fn renumbered_bodies_move_on_as_before() {
        let mut before = heap();
        let mut after = before.clone();
        let pairs = (after.contacts.keys())
            .filter(|k| matches!(k.0, Partner::Body(_)))
            .count();

        assert!(pairs >= 6, "{pairs} contacts between bodies");
        let new_id = after.renumber_along_space();
        assert_ne!(
            new_id,
            (0..12).collect::<Vec<u32>>(),
            "the bodies were built out of order"
        );
        // The same contacts, under the new ids; a pair whose ids swap order swaps its normal.
        assert_eq!(after.contacts.len(), before.contacts.len());
        let mut swapped = 0;
        for (&(partner, b), c) in &before.contacts {
            let Partner::Body(a) = partner else {
                continue;
            };
            let (a2, b2) = (new_id[a as usize], new_id[b as usize]);
            let key = (Partner::Body(a2.min(b2)), a2.max(b2));
            let moved = after
                .contacts
                .get(&key)
                .expect("the contact follows its bodies");
            let sign = if a2 < b2 { 1.0 } else { -1.0 };
            swapped += usize::from(a2 > b2);
            assert_eq!(moved.normal, c.normal * sign);
            assert_eq!(moved.shear, c.shear * sign);
            assert_eq!(moved.potential, c.potential);
        }
        assert!(
            swapped > 0,
            "no contact swapped its bodies: the flip is untested"
        );
        // The same motion to round-off (only the order of sums differs).
        for _ in 0..300 {
            before.step();
            after.step();
        }
        for (i, b) in before.bodies.iter().enumerate() {
            let moved = &after.bodies[new_id[i] as usize];
            assert!(
                (moved.pos - b.pos).norm() < 1e-12,
                "body {i}: {:e} m apart",
                (moved.pos - b.pos).norm()
            );
            assert!(moved.rot.angle_to(&b.rot) < 1e-10, "body {i} turned apart");
        }
        // Ordered already (the bodies have moved since: order them again first), a second
        // renumbering changes nothing.
        after.renumber_along_space();
        let again = after.renumber_along_space();
        assert_eq!(again, (0..12).collect::<Vec<u32>>());
    }

    #[test]
    fn no_point_of_a_body_moves_farther_than_its_motion_bound() {
        let shape = Shape::from_mesh(&cuboid(Vec3::new(0.02, 0.005, 0.01))).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut w = World::new(Material::default(), Vec3::zeros());
        let s = w.add_shape(shape);
        let i = w.add_body(s, 1.5, Vec3::new(0.1, -0.2, 0.3), random_rotation(&mut rng));
        let mut tightest = f64::INFINITY;
        for trial in 0..2000 {
            let before = w.bodies[i].clone();
            let placed = Placed::of(&before);
            let small = trial % 2 == 0;
            let (shift, turn) = if small { (1e-6, 1e-5) } else { (1e-2, 3.0) };
            let b = &mut w.bodies[i];
            b.pos += Vec3::from_fn(|_, _| rng.random_range(-shift..shift));
            let axis = Vec3::from_fn(|_, _| rng.random_range(-1.0..1.0));
            b.rot = UnitQuaternion::from_scaled_axis(axis * rng.random_range(0.0..turn)) * b.rot;
            let radius = w.shapes[s as usize].radius * b.scale;
            let bound = placed.moved(b, radius);
            let farthest = w.shapes[s as usize]
                .vertices
                .iter()
                .map(|v| {
                    let at = |b: &Body| b.pos + b.rot * (v * b.scale);
                    (at(b) - at(&before)).norm()
                })
                .fold(0.0, f64::max);
            assert!(
                farthest <= bound * (1.0 + 1e-12),
                "trial {trial}: {farthest} > {bound}"
            );
            tightest = tightest.min(bound / farthest);
        }
        // A bound, not a loose guess: the centroid's shift and the chord of the largest radius.
        assert!(tightest < 1.5, "the bound is never tight: {tightest}");
        // A body that grew, or took another shape, and moved: its points are within the
        // centroid's shift and its new radius of the old centroid.
        for change in 0..2 {
            let mut b = w.bodies[i].clone();
            let placed = Placed::of(&b);
            if change == 0 {
                b.scale *= 1.0 + 1e-9;
            } else {
                b.shape += 1;
            }
            b.pos += Vec3::new(1e-3, -2e-3, 0.0);
            let expected = 5f64.sqrt() * 1e-3 + 0.25;
            assert!(
                (placed.moved(&b, 0.25) - expected).abs() < 1e-15,
                "change {change}"
            );
        }
    }

    /// Twelve cubes and bars thrown at each other, with and without the kept gap proofs.
    fn thrown(seed: u64) -> World {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let material = Material {
            kn: 1e6,
            ks: 5e5,
            ..Material::default()
        };
        let mut w = World::new(material, Vec3::zeros());
        let c = w.add_shape(Shape::from_mesh(&cube(0.5)).unwrap());
        let bar = w.add_shape(Shape::from_mesh(&cuboid(Vec3::new(1.0, 0.5, 0.5))).unwrap());
        for k in 0..12 {
            let at = Vec3::new((k % 3) as f64, ((k / 3) % 2) as f64, (k / 6) as f64) * 0.05;
            let i = w.add_body([c, bar][k % 2], 0.02, at, random_rotation(&mut rng));
            let centre = Vec3::new(0.05, 0.025, 0.025);
            w.bodies[i].vel =
                (centre - at) * 15.0 + Vec3::from_fn(|_, _| rng.random_range(-0.05..0.05));
            w.bodies[i].ang_mom = Vec3::from_fn(|_, _| rng.random_range(-1e-6..1e-6));
        }
        w.dt = 0.2 * w.critical_dt();
        w
    }

    #[test]
    fn kept_gap_proofs_change_no_result() {
        let (mut kept, mut fresh) = (thrown(5), thrown(5));
        let (mut carried, mut contacts) = (0, 0);
        for step in 0..3000 {
            kept.step();
            fresh.separations = Separations::default();
            fresh.step();
            // (The structures kept differ: fresh proofs, fresh odometers, none kept.)
            let state =
                |w: &World| format!("{:?}{:?}", w.bodies, w.contacts.iter().collect::<Vec<_>>());
            assert_eq!(state(&kept), state(&fresh), "step {step}");
            contacts += kept.contacts.len();
            let odometers = &kept.separations.odometers;
            carried += (kept.separations.in_force())
                .filter(|g| g.travel[0] != odometers[g.pair.0 as usize].travel)
                .count();
        }
        assert!(
            contacts > 500,
            "the bodies hardly met: {contacts} contact-steps"
        );
        assert!(carried > 1000, "proofs carried only {carried} times");
    }

    #[test]
    fn a_body_moved_by_hand_past_its_gap_is_found_touching() {
        use std::f64::consts::FRAC_PI_4;
        let mut w = World::new(Material::default(), Vec3::zeros());
        let c = w.add_shape(Shape::from_mesh(&cube(0.5)).unwrap());
        let bar = w.add_shape(Shape::from_mesh(&cuboid(Vec3::new(2.0, 0.5, 0.5))).unwrap());
        let turned = |angle: f64| UnitQuaternion::from_scaled_axis(Vec3::z() * angle);
        // A 20 mm cube turned 45 degrees: a face looks along the diagonal, 10 mm out.
        w.add_body(c, 0.02, Vec3::zeros(), turned(FRAC_PI_4));
        // A 40 x 10 x 10 mm bar across that diagonal, 16 mm out: 1 mm clear of the face, its
        // box well over the cube's, so the pair needs a gap proof every step.
        let out = |d: f64| Vec3::new(1.0, 1.0, 0.0).normalize() * d;
        w.add_body(bar, 0.01, out(0.016), turned(-FRAC_PI_4));
        w.dt = 0.1 * w.critical_dt();
        for _ in 0..3 {
            w.step();
            assert!(w.contacts.is_empty());
        }
        assert!(w.separations.get((0, 1)).is_some(), "no gap proof kept");
        // Turned by hand along the diagonal: it now reaches 4 mm past the cube's centre.
        w.bodies[1].rot = turned(FRAC_PI_4);
        w.step();
        assert_eq!(w.contacts.len(), 1, "a turn past the gap");
        // Put back clear, then pushed in by hand 0.5 mm past the face.
        w.bodies[1].rot = turned(-FRAC_PI_4);
        for b in &mut w.bodies {
            b.vel = Vec3::zeros();
            b.ang_mom = Vec3::zeros();
        }
        w.bodies[0].pos = Vec3::zeros();
        w.bodies[0].rot = turned(FRAC_PI_4);
        w.bodies[1].pos = out(0.016);
        for _ in 0..3 {
            w.step();
            assert!(w.contacts.is_empty());
        }
        assert!(w.separations.get((0, 1)).is_some(), "no gap proof kept");
        w.bodies[1].pos = out(0.0145);
        w.step();
        assert_eq!(w.contacts.len(), 1, "a shift past the gap");
        // Put back clear, then grown by hand in place: 10 mm thick to 13 mm reaches 0.5 mm
        // past the face.
        w.bodies[1].pos = out(0.016);
        for b in &mut w.bodies {
            b.vel = Vec3::zeros();
            b.ang_mom = Vec3::zeros();
        }
        for _ in 0..3 {
            w.step();
            assert!(w.contacts.is_empty());
        }
        assert!(w.separations.get((0, 1)).is_some(), "no gap proof kept");
        w.bodies[1].scale = 0.013;
        w.step();
        assert_eq!(w.contacts.len(), 1, "a growth past the gap");
    }
}
