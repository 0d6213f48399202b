//! The DEM world: bodies, walls, contacts, and one time step.
//!
//! Physics (the paper's, PFC-like):
//! - contact geometry from the overlap polyhedron ([`super::overlap`]): normal `n` from A to B,
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

use super::broad::{overlap as overlap_boxes, Aabb, Broad};
use super::contacts::{Carry, Contacts, Cursor, Part};
use super::gjk::Hints;
use super::overlap::{
    centre_line, gap_proof, overlap_kept, overlap_kept_or, Found, GapProof, Overlap, WallFound,
};
use super::shape::{
    motion_bound, travel_after, Posed, Remade, Shape, Travel, TRAVEL_UNIT, TRAVEL_UNKNOWN,
};
use super::spread::spread;
use super::structure::Structure;
use super::wall::{FacetGrid, Wall, WallKind};
use crate::math::{cube, pow5, Vec3};
use nalgebra::UnitQuaternion;
use rayon::prelude::*;

/// Material and contact parameters (SI units). Defaults are the paper's Table 1.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// kg/m^3
    pub density: f64,
    /// Normal stiffness, N/m.
    pub kn: f64,
    /// Shear stiffness, N/m.
    pub ks: f64,
    /// Particle-particle friction coefficient.
    pub friction: f64,
    /// Particle-wall friction coefficient (the paper: 0).
    pub wall_friction: f64,
    /// Local damping coefficient alpha (0..1).
    pub damping: f64,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            density: 2600.0,
            kn: 1e8,
            ks: 5e7,
            friction: 0.5,
            wall_friction: 0.0,
            damping: 0.3,
        }
    }
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

    /// [`Body::velocity_at`] with the body's angular velocity `omega` ([`Body::omega`]) as
    /// computed already.
    fn velocity_with(&self, omega: &Vec3, p: &Vec3) -> Vec3 {
        if self.fixed {
            return Vec3::zeros();
        }
        self.vel + omega.cross(&(p - self.pos))
    }
}

/// What a body touches.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Partner {
    Body(u32),
    Wall(u32),
}

/// One contact: geometry, forces (on body `b` of the key; the partner `a` gets the opposite),
/// and the shear spring carried to the next step.
#[derive(Clone, Debug, PartialEq)]
pub struct Contact {
    /// Unit normal from the partner to the body.
    pub normal: Vec3,
    pub point: Vec3,
    pub depth: f64,
    pub normal_force: f64,
    /// Energy stored by the normal force: the work done against it since the contact began,
    /// summed step by step with the trapezoidal rule. The depth `V / |S_B|` is not the
    /// distance the force moves through: for faces pressed flat together this is
    /// `Fn^2 / 2kn` exactly, for a vertex pressed into a face three times that.
    pub potential: f64,
    pub shear: Vec3,
    pub sliding: bool,
}

impl Contact {
    /// Energy stored in the normal and shear springs: `potential + |Fs|^2 / 2ks` (no shear term
    /// without a shear spring).
    pub fn elastic_energy(&self, m: &Material) -> f64 {
        let shear = if m.ks > 0.0 {
            0.5 * self.shear.norm_squared() / m.ks
        } else {
            0.0
        };
        self.potential + shear
    }
}

/// The energy a contact stores when its force has grown linearly over its depth (faces pressed
/// flat, `Fn^2 / 2kn`): where a contact's stored work starts, new or re-stiffened.
fn flat_potential(normal_force: f64, depth: f64) -> f64 {
    0.5 * normal_force * depth
}

/// Key of a contact: (partner, body), the body being B (the normal points to it). For body pairs
/// the partner has the lower index.
pub type ContactKey = (Partner, u32);

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
    broad: Broad,
    buffers: Buffers,
    /// Whether contacts keep their overlap's structure for the next step ([`super::structure`]).
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

/// Gap proofs, one slot per pair of the broad phase's kept list ([`Broad::candidates`]), in
/// its order: a step updates them in place. (Made anew each step, the list of the pairs proven
/// apart was copied forward whole, 2 MB a step on the 2000 I_P bed, most of it unchanged: 3 % of
/// a step's time in the copy alone.) A slot may hold a proof from any earlier step: whether it
/// still holds is checked by the bodies' travel since, every time it is used.
#[derive(Clone, Debug, Default)]
struct Separations {
    slots: Vec<Option<Gap>>,
    /// Per slot, the largest sum of the two bodies' odometer readings under which its proof
    /// holds ([`Gap::limit`]), or 0 for none: the one word a step reads for a pair proven
    /// apart. (The check read the 64-byte slot, which spans two cache lines as often as not:
    /// the slots of the 5000 I_P bed's ~56 000 pairs, 3.6 MB, were the step's most missed
    /// loads; the limits are 450 KB.) A slot whose limit is 0 holds no proof.
    limits: Vec<Travel>,
    /// Per body, where it was at the last step and how far its points may have travelled since
    /// the odometers were set: what the proofs are checked against.
    odometers: Vec<Odometer>,
}

/// A pair `(i, j)`, `i < j`, proven apart: the proof, the supports it ended on, and both bodies'
/// odometer readings when it was made. (It held both bodies' poses, 144 of its 216 bytes: on the
/// 5000 I_P bed 12 MB of slots a step, and their first reads were the step's most missed
/// loads.)
#[derive(Clone, Copy, Debug)]
struct Gap {
    pair: (u32, u32),
    proof: GapProof,
    hints: PackedHints,
    travel: [Travel; 2],
}

/// [`Hints`] in 8 bytes rather than 32 (`u32::MAX` for none): with them a gap slot is 64 bytes.
#[derive(Clone, Copy, Debug)]
struct PackedHints([u32; 2]);

impl Gap {
    /// The largest sum of the two bodies' odometer readings `t0 + t1` under which the proof
    /// holds: their travel since, `(t0 - g0) + (t1 - g1)` units, is then less than the spare
    /// distance `spare / TRAVEL_UNIT` (a power of two: exact), and the pair is apart. 0 (no
    /// sum is below it) when a reading was unknown or nothing is spare; rounded down where the
    /// sum would run out of range.
    fn limit(&self) -> Travel {
        let [g0, g1] = self.travel;
        let units = (self.proof.spare / TRAVEL_UNIT).ceil();
        if g0 == TRAVEL_UNKNOWN || g1 == TRAVEL_UNKNOWN || units.is_nan() || units <= 0.0 {
            return 0;
        }
        // `as` saturates at u64::MAX for a spare beyond the range (16 km).
        g0.saturating_add(g1).saturating_add(units as u64)
    }

    /// Whether the proof still holds with the bodies' readings now `t0` and `t1`, given its
    /// [`Gap::limit`] (an unknown reading saturates the sum: no).
    fn holds(limit: Travel, t0: Travel, t1: Travel) -> bool {
        t0.saturating_add(t1) < limit
    }
}

impl PackedHints {
    fn of(hints: &Hints) -> PackedHints {
        PackedHints(hints.map(|h| h.map_or(u32::MAX, |k| k as u32)))
    }

    fn hints(&self) -> Hints {
        self.0.map(|h| (h != u32::MAX).then_some(h as usize))
    }
}

/// What [`World::pose_all`] gives per body besides its pose, each in a list of its own (the
/// narrow phase reads them for every pair, most of which never need the pose).
struct Poses {
    boxes: Vec<Aabb>,
    /// The walls each box may touch (bit `w` for wall `w < 64`; walls from 64 on are all
    /// marked).
    reach: Vec<u64>,
    /// The odometer readings ([`Posed::travel`]).
    travels: Vec<Travel>,
    /// The angular velocities ([`Body::omega`]): each contact reads two, and computing them
    /// there (a quaternion turn each way and three divisions) was ~2 % of a step.
    omegas: Vec<Vec3>,
}

/// A body's odometer: where it was at the last step, and the sum of each step's motion bound
/// since the odometer was set, a bound on how far any of its points has moved since then.
#[derive(Clone, Copy, Debug)]
struct Odometer {
    at: Placed,
    travel: Travel,
}

impl Odometer {
    /// Read for body `b`, bounding radius `radius` about its centroid: the travel since `at`
    /// added, and `at` moved to `b`.
    fn advance(&mut self, b: &Body, radius: f64) {
        self.travel = travel_after(self.travel, self.at.moved(b, radius));
        self.at = Placed::of(b);
    }
}

/// Where a body was, as far as its points are concerned.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Placed {
    pos: Vec3,
    rot: UnitQuaternion<f64>,
    scale: f64,
    shape: u32,
}

impl Placed {
    fn of(b: &Body) -> Placed {
        Placed {
            pos: b.pos,
            rot: b.rot,
            scale: b.scale,
            shape: b.shape,
        }
    }

    /// A bound on how far any point of `b` (bounding radius `radius` about its centroid) is
    /// from the body as it was here ([`motion_bound`]). When the body changed its shape or size
    /// since, the points are no longer the same: every point of `b` is then within the
    /// centroid's shift plus `radius` of the old centroid, a point of the old (convex) body.
    fn moved(&self, b: &Body, radius: f64) -> f64 {
        if b.scale != self.scale || b.shape != self.shape {
            return (b.pos - self.pos).norm() + radius;
        }
        motion_bound((&self.pos, &self.rot), (&b.pos, &b.rot), radius)
    }
}

impl Separations {
    /// Slots for a new kept list `listed` (ascending), each with its pair's proof from these
    /// slots, if any (theirs are ascending by pair too).
    fn realigned(self, listed: &[(u32, u32)]) -> Separations {
        let mut old = self.in_force().peekable();
        let slot = |&pair: &(u32, u32)| {
            while old.next_if(|g| g.pair < pair).is_some() {}
            old.next_if(|g| g.pair == pair).copied()
        };
        let slots: Vec<Option<Gap>> = listed.iter().map(slot).collect();
        drop(old);
        let limits = (slots.iter()).map(|g| g.map_or(0, |g| g.limit())).collect();
        Separations {
            slots,
            limits,
            odometers: self.odometers,
        }
    }

    /// The proofs in force (those whose limit is not 0), in slot order.
    fn in_force(&self) -> impl Iterator<Item = &Gap> {
        (self.slots.iter().zip(&self.limits))
            .filter_map(|(g, &limit)| g.as_ref().filter(|_| limit != 0))
    }

    /// No proofs, and an odometer for each of `bodies` set at zero.
    fn new(bodies: &[Body]) -> Separations {
        let odometer = |b: &Body| Odometer {
            at: Placed::of(b),
            travel: 0,
        };
        Separations {
            slots: Vec::new(),
            limits: Vec::new(),
            odometers: bodies.iter().map(odometer).collect(),
        }
    }

    /// The gap proof of pair `(i, j)` kept, if any.
    #[cfg(test)]
    fn get(&self, pair: (u32, u32)) -> Option<&Gap> {
        self.in_force().find(|g| g.pair == pair)
    }
}

/// What a wall contact hands back beside its [`Touch`] (kept apart, so that the touches,
/// written by one thread and read by the other, are a fifth smaller).
struct WallExtra {
    /// For facet walls: the share of the force each node carries.
    node_weights: Vec<(u32, f64)>,
    /// For a wall contact in separate spots: the moment of the spots' pushes about the
    /// contact point, on top of `point x force` ([`super::wall::WallHit::couple`] times `kn`).
    couple: Vec3,
    /// Work the partner's surface did on the body over the step, J: the mean of the last and
    /// this step's force over the surface's displacement (as the contact's stored work counts
    /// it).
    wall_work: f64,
    /// The wall set to keep ([`super::overlap::overlap_half_space_kept`]), and the contact's
    /// place in the last list (where a kept set is).
    found: WallFound,
    at: usize,
}

/// A run of wall contacts' part of the contact list, and their touches.
type WallChunk = (Part, Vec<(Touch, WallExtra)>);

/// An item of a step's narrow phase: a chunk of body pairs with their gap slots, or a run of
/// (body, wall) pairs.
enum Work<'a> {
    Pairs(&'a [(u32, u32)], &'a mut [Option<Gap>], &'a mut [Travel]),
    Walls(&'a [(u32, u32)]),
}

/// What an item of [`Work`] gives.
enum Done {
    Pairs(Chunk),
    Walls(WallChunk),
}

/// [`World::alternates`]: by body pair, the shapes and the structure.
type Alternates = std::collections::HashMap<(u32, u32), ([u32; 2], Structure)>;

/// Every this many steps, the alternates of pairs no longer in contact are dropped.
const ALTERNATES_PRUNED: u64 = 64;

/// What the narrow phase hands back for one touching pair.
struct Touch {
    force: Vec3,
    /// The contact's point (where the force acts).
    point: Vec3,
    slip_energy: f64,
    /// The overlap's structure, to keep for the next step: `Found::Kept` is the one the contact
    /// kept, at `at` in the last step's list.
    kept: Found,
    at: usize,
    /// The structure kept at `at` stopped holding: it becomes the pair's alternate.
    retired: bool,
}

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

    /// Poses every body into `posed`, reusing its buffers; returns each body's box, the
    /// walls that box may touch, its odometer reading and angular velocity ([`Poses`]), made
    /// in the same pass (a serial pass over the posed bodies for the boxes and over
    /// walls x boxes for the walls took 2.5 % of a step of the 2000 I_P bed on 2 threads, and
    /// let the other thread fall asleep twice a step).
    fn pose_all(
        &self,
        posed: &mut Vec<Posed>,
        odometers: &mut [Odometer],
        grids: &[Option<FacetGrid>],
    ) -> Poses {
        posed.resize_with(self.bodies.len(), Posed::default);
        // Large hulls are posed lazily while their shapes' vertices stay in cache.
        let large: usize = (self.shapes.iter())
            .filter(|s| s.climb.is_some())
            .map(|s| s.vertices.len() * std::mem::size_of::<Vec3>())
            .sum();
        let lazy = large <= LAZY_HULLS_MAX_BYTES;
        let walls = &self.walls;
        let pose = |((b, p), odometer): ((&Body, &mut Posed), &mut Odometer)| {
            let shape = &self.shapes[b.shape as usize];
            shape.pose_for_contacts(&b.pos, &b.rot, b.scale, p, lazy);
            odometer.advance(b, shape.radius * b.scale);
            p.travel = Some(odometer.travel);
            let reach = (walls.iter().zip(grids).enumerate())
                .filter(|(w, (wall, grid))| *w >= 64 || wall.may_touch(&p.lo, &p.hi, grid.as_ref()))
                .fold(0u64, |bits, (w, _)| bits | 1 << w.min(63));
            ((p.lo, p.hi), reach, odometer.travel, b.omega())
        };
        let blocks = (self.bodies.chunks(POSE_BLOCK))
            .zip(posed.chunks_mut(POSE_BLOCK))
            .zip(odometers.chunks_mut(POSE_BLOCK));
        let blocks = spread(
            blocks.collect(),
            parallel(self.bodies.len()),
            |((b, p), o)| b.iter().zip(p).zip(o).map(pose).collect::<Vec<_>>(),
        );
        // Into lists made to size (unzipped, they grew by doubling: 0.7 % of a step's
        // instructions on the 5000 I_P bed).
        let n = self.bodies.len();
        let mut poses = Poses {
            boxes: Vec::with_capacity(n),
            reach: Vec::with_capacity(n),
            travels: Vec::with_capacity(n),
            omegas: Vec::with_capacity(n),
        };
        for (bx, reach, travel, omega) in blocks.into_iter().flatten() {
            poses.boxes.push(bx);
            poses.reach.push(reach);
            poses.travels.push(travel);
            poses.omegas.push(omega);
        }
        poses
    }

    /// How many times the broad phase has swept all boxes since this world was made or read
    /// (the other steps filtered its kept list of pairs; see [`super::broad`]).
    pub fn broad_sweeps(&self) -> u64 {
        self.broad.sweeps
    }

    /// Contact forces of one touching pair from its overlap.
    /// `omega`: the angular velocity of the key's body; `last`: the contact of `key` last
    /// step, if any.
    fn touch(
        &self,
        key: ContactKey,
        omega: &Vec3,
        last: Option<&Contact>,
        o: &Overlap,
        va: Vec3,
        friction: f64,
    ) -> (Contact, Touch) {
        let m = &self.material;
        let b = &self.bodies[key.1 as usize];
        let (n, depth) = o.normal_depth();
        let fn_ = m.kn * depth;
        let point = o.centroid;
        let rel = b.velocity_with(omega, &point) - va;
        let vt = rel - n * n.dot(&rel);
        // Work against the normal force over the step (the mean of the last and this step's
        // force over the contact point's relative displacement), stored as the contact's
        // energy. A new contact starts as if pressed flat: exact for a scene built with
        // overlaps of flat contacts, and a step's penetration otherwise.
        let potential = match last {
            Some(c) => {
                c.potential - 0.5 * (c.normal * c.normal_force + n * fn_).dot(&rel) * self.dt
            }
            None => flat_potential(fn_, depth),
        };
        // Carry the stored shear force onto the new tangent plane, keeping its magnitude.
        let old = last.map_or(Vec3::zeros(), |c| c.shear);
        let mut shear = old - n * n.dot(&old);
        let len = shear.norm();
        if len > 0.0 {
            shear *= old.norm() / len;
        }
        let trial = shear - vt * (m.ks * self.dt);
        let limit = friction * fn_;
        let t = trial.norm();
        let (shear, sliding, slip_energy) = if t > limit {
            // Energy lost in the slip: the limit force over the slip (t - limit) / ks.
            (trial * (limit / t), true, limit * (t - limit) / m.ks)
        } else {
            (trial, false, 0.0)
        };
        let contact = Contact {
            normal: n,
            point,
            depth,
            normal_force: fn_,
            potential,
            shear,
            sliding,
        };
        let touch = Touch {
            force: n * fn_ + shear,
            point,
            slip_energy,
            kept: Found::None,
            retired: false,
            at: 0,
        };
        (contact, touch)
    }

    /// Advances the world by one time step `dt`.
    pub fn step(&mut self) {
        assert!(
            self.dt > 0.0,
            "set World::dt before stepping (see critical_dt)"
        );
        let dt = self.dt;
        let clock = std::time::Instant::now();
        let mut lap = {
            let mut last = clock;
            move || {
                let now = std::time::Instant::now();
                let secs = (now - last).as_secs_f64();
                last = now;
                secs
            }
        };
        // The walls move first, so this step's contacts see each wall's displacement since
        // the last step's forces at the velocity it moved with (a servo sets the velocity
        // between steps; moved after the forces, the contacts saw the next step's velocity
        // against the bodies' last, and the stored work drifted by each change of speed).
        for w in &mut self.walls {
            w.advance(dt);
        }
        let mut posed = std::mem::take(&mut self.posed);
        let par = parallel(self.bodies.len());
        let _awake = par.then(Awake::new);
        // Facet walls' triangles by place, for this step's nodes and the largest body.
        let faceted = (self.walls.iter()).any(|w| matches!(w.kind, WallKind::Facets { .. }));
        let largest = (self.bodies.iter())
            .filter(|_| faceted)
            .map(|b| self.shapes[b.shape as usize].radius * b.scale)
            .fold(0.0, f64::max);
        let grids: Vec<Option<FacetGrid>> = (self.walls.iter())
            .map(|w| FacetGrid::of(w, largest))
            .collect();
        let mut gaps = std::mem::take(&mut self.separations);
        if gaps.odometers.len() != self.bodies.len() {
            // Odometers anew (a new world, or bodies added or taken away): the readings kept
            // with the gap proofs and structures no longer compare with theirs.
            gaps = Separations::new(&self.bodies);
            self.contacts.take_kept();
            self.alternates.clear();
        }
        let Poses {
            boxes,
            reach,
            travels,
            omegas,
        } = self.pose_all(&mut posed, &mut gaps.odometers, &grids);
        let mut broad = std::mem::take(&mut self.broad);
        let (pairs, swept) = broad.candidates(&boxes, par);
        let mut buffers = std::mem::take(&mut self.buffers);
        let threads = rayon::current_num_threads();
        buffers.0.resize_with(threads + 1, Default::default);
        let buffers_ref = &buffers;
        if swept || gaps.slots.len() != pairs.len() {
            gaps = gaps.realigned(pairs);
        }
        self.times.broad += lap();
        // `at`: where this chunk's walk over the contact list is (see `Contacts::seek`).
        // `slot`: the pair's gap proof, kept or made here, in force while its `limit` is not 0
        // (a contact leaves none).
        let narrow = |&(i, j): &(u32, u32),
                      at: &mut Cursor,
                      (slot, limit): (&mut Option<Gap>, &mut Travel)| {
            // The boxes and odometer readings from their compact lists: a pair that is not
            // touching is told so without reading the poses (a line or two each, out of cache).
            if !overlap_boxes(&boxes[i as usize], &boxes[j as usize]) {
                return None;
            }
            let key = (Partner::Body(i), j);
            // Warm start: the last normal bounds this step's overlap most tightly; a new pair
            // is first tested for a gap, from the direction that proved it last step.
            let last = self.contacts.seek(at, &key);
            let travel = [travels[i as usize], travels[j as usize]];
            // Still apart when the two bodies' travel since the proof is less than its spare
            // distance: the pair is then more than the proof's margin apart, where the full
            // test answers the same (no contact).
            if last.is_none() && Gap::holds(*limit, travel[0], travel[1]) {
                return None;
            }
            let (pi, pj) = (&posed[i as usize], &posed[j as usize]);
            let (bi, bj) = (&self.bodies[i as usize], &self.bodies[j as usize]);
            if bi.fixed && bj.fixed {
                return None;
            }
            let (si, sj) = (
                &self.shapes[bi.shape as usize],
                &self.shapes[bj.shape as usize],
            );
            let mut had = false;
            let (o, kept) = match last {
                Some((c, kept)) => {
                    let kept = kept.filter(|_| self.keep_structures);
                    had = kept.is_some();
                    let alternate = || {
                        let (shapes, s) = self.alternates.get(&(i, j))?;
                        (*shapes == [bi.shape, bj.shape]).then(|| s.packed())
                    };
                    overlap_kept_or(si, pi, sj, pj, &c.normal, kept, alternate, true)
                }
                None => {
                    let line = centre_line(pi, pj);
                    let (start, mut hints) = (slot.filter(|_| *limit != 0))
                        .map_or((line, Hints::default()), |g| {
                            (g.proof.axis, g.hints.hints())
                        });
                    if let Some(proof) = gap_proof(si, pi, sj, pj, &start, &mut hints) {
                        let gap = Gap {
                            pair: (i, j),
                            proof,
                            hints: PackedHints::of(&hints),
                            travel,
                        };
                        (*slot, *limit) = (Some(gap), gap.limit());
                        return None;
                    }
                    // A new contact is clipped: finding a structure costs more than that,
                    // and pays only for contacts that last (the rule depends on the state
                    // alone, so a restart takes the same path).
                    overlap_kept(si, pi, sj, pj, &line, None, false)
                }
            }?;
            // (The slot itself is left as it is: a contact pair need not load its line.)
            *limit = 0;
            let va = bi.velocity_with(&omegas[i as usize], &o.centroid);
            let last = last.map(|(c, _)| c);
            let (contact, mut touch) = self.touch(
                key,
                &omegas[j as usize],
                last,
                &o,
                va,
                self.material.friction,
            );
            // `at` is still where the seek left it: the contact's place, when it had one.
            // Alternates only for large hulls, whose structures cost most to find (for two
            // I_P bodies, keeping and trying them cost more than finding one afresh).
            let large = si.climb.is_some() || sj.climb.is_some();
            touch.retired = had && large && !matches!(kept, Found::Kept);
            (touch.kept, touch.at) = (kept, at.index());
            Some((key, contact, touch))
        };
        // Each chunk of pairs keeps its own touches, so no thread copies another's results into
        // one list (that copy was 4 % of a step on 2 threads): the touches are then referenced
        // in pair order.
        let contacts = &self.contacts;
        let chunk = |pairs: &[(u32, u32)], slots: &mut [Option<Gap>], limits: &mut [Travel]| {
            let owner = Buffers::slot(threads);
            let (mut touches, mut touching, mut part) = buffers_ref.take(owner);
            // Room for every pair: growing the list by doubling (realloc copies of 200-byte
            // items) was 6 % of a step's instructions on the 2000 I_P bed.
            touches.reserve(pairs.len());
            part.reserve(pairs.len());
            part.tag = owner;
            let mut at = (pairs.first()).map_or_else(Cursor::default, |&(i, j)| {
                contacts.cursor(&(Partner::Body(i), j))
            });
            // The touching pairs again, compact, for the force rows (read from the touches
            // themselves, a cache line each, often in the other core's cache, they took 2.5x
            // as long on 2 threads as on one).
            // The energy sums too, while each touch is in this core's cache (summed over the
            // list afterwards, the touches made by the other core took 2.4x as long to read).
            let mut sums = Sums::default();
            for ((pair, slot), limit) in pairs.iter().zip(slots).zip(limits) {
                if let Some((key, contact, t)) = narrow(pair, &mut at, (slot, limit)) {
                    sums.add(&contact, &t, &self.material);
                    part.push(key, contact);
                    touches.push(t);
                    touching.push(*pair);
                }
            }
            Chunk {
                touches,
                touching,
                part,
                owner,
                sums,
            }
        };
        let this = &*self;
        // By wall, then body: the order of the contact keys, so the touches come out sorted.
        // (A body still adds its wall contacts by ascending wall, as each wall its bodies.)
        // Only the bodies whose boxes reach a wall (marked as they were posed: the wall
        // contacts' own test read each body and its pose, a cache miss or two for each of
        // the walls x bodies pairs).
        let wall_pairs: Vec<(u32, u32)> = (0..this.walls.len())
            .flat_map(|w| {
                let bit = 1u64 << w.min(63);
                (reach.iter().enumerate())
                    .filter(move |(_, r)| *r & bit != 0)
                    .map(move |(i, _)| (i as u32, w as u32))
            })
            .collect();
        // A run of wall contacts: its part of the contact list, and the touches.
        let wall_touches = |wall_pairs: &[(u32, u32)]| -> WallChunk {
            let mut part = buffers_ref.take_part(Buffers::slot(threads));
            // The keys ascend, so one cursor walks the last list's wall contacts.
            let mut at = (wall_pairs.first()).map_or_else(Cursor::default, |&(i, w)| {
                this.contacts.cursor(&(Partner::Wall(w), i))
            });
            // Room for every pair (grown by doubling, the ~250-byte items were copied over).
            let mut touches = Vec::with_capacity(wall_pairs.len());
            touches.extend((wall_pairs.iter()).filter_map(|&(i, w)| {
                let b = &this.bodies[i as usize];
                if b.fixed {
                    return None;
                }
                let wall = &this.walls[w as usize];
                let shape = &this.shapes[b.shape as usize];
                let key = (Partner::Wall(w), i);
                let (last, kept) = match this.contacts.seek(&mut at, &key) {
                    Some((c, kept)) => (Some(c), kept.filter(|_| this.keep_structures)),
                    None => (None, None),
                };
                let kept = kept.map(|k| k.words());
                let radius = shape.radius * b.scale;
                let grid = grids[w as usize].as_ref();
                let (hit, found) =
                    wall.touch_kept(shape, &posed[i as usize], radius, kept, grid)?;
                let (mut contact, t) = this.touch(
                    key,
                    &omegas[i as usize],
                    last,
                    &hit.overlap,
                    hit.velocity,
                    this.material.wall_friction,
                );
                let last_force =
                    last.map_or(Vec3::zeros(), |c| c.normal * c.normal_force + c.shear);
                let mut extra = WallExtra {
                    node_weights: hit.node_weights,
                    couple: Vec3::zeros(),
                    wall_work: 0.5 * (last_force + t.force).dot(&hit.velocity) * this.dt,
                    found,
                    at: at.index(),
                };
                if hit.couple != Vec3::zeros() {
                    // The spots' moment does work as the body turns (the wall does not).
                    extra.couple = hit.couple * this.material.kn;
                    contact.potential -= extra.couple.dot(&omegas[i as usize]) * this.dt;
                }
                part.push(key, contact);
                Some((t, extra))
            }));
            (part, touches)
        };
        // The body pairs in chunks, then the wall contacts, all spread over the threads (the
        // other thread starts from the back: the walls). Plane and cylinder walls are one
        // serial run: split among threads, each contact took twice as long (on the 2000 I_P
        // bed, 0.44 us a contact on one thread; the poses and bodies they read were in the
        // other core's cache half the time). A facet wall's contact costs tens of times that
        // (each triangle near the body cut from it), so with facet walls the wall contacts
        // come in short runs that either thread takes: in one run, they held the step up
        // while the other thread waited (100 steps of the 2000 I_P bed with its sides as
        // facets, 2 threads: 0.77-0.78 s in one run, 0.63-0.67 s in runs of 8).
        const CHUNK: usize = 256;
        const FACET_CHUNK: usize = 8;
        let wall_chunk = if grids.iter().any(Option::is_some) {
            FACET_CHUNK
        } else {
            wall_pairs.len().max(1)
        };
        let items: Vec<Work> = (pairs.chunks(CHUNK).zip(gaps.slots.chunks_mut(CHUNK)))
            .zip(gaps.limits.chunks_mut(CHUNK))
            .map(|((p, g), l)| Work::Pairs(p, g, l))
            .chain(wall_pairs.chunks(wall_chunk).map(Work::Walls))
            .collect();
        let work = |item: Work| match item {
            Work::Pairs(p, g, l) => Done::Pairs(chunk(p, g, l)),
            Work::Walls(w) => Done::Walls(wall_touches(w)),
        };
        let (mut chunks, mut wall_parts, mut wall_touches) = (Vec::new(), Vec::new(), Vec::new());
        for done in spread(items, par, work) {
            match done {
                Done::Pairs(c) => chunks.push(c),
                Done::Walls((part, touches)) => {
                    wall_parts.push(part);
                    wall_touches.extend(touches);
                }
            }
        }
        self.broad = broad;
        self.separations = gaps;
        // The contact list is made of the chunks' parts, as they are.
        let mut parts: Vec<Part> = (chunks.iter_mut())
            .map(|c| std::mem::take(&mut c.part))
            .collect();
        let wall_keys: Vec<ContactKey> = (wall_parts.iter())
            .flat_map(|p| p.keys().iter().copied())
            .collect();
        let pair_parts = parts.len();
        parts.extend(wall_parts);
        // Made to size: collected from the chunks, the list grew by doubling (serially).
        let pair_touches: usize = chunks.iter().map(|c| c.touches.len()).sum();
        let mut touches: Vec<&Touch> = Vec::with_capacity(pair_touches + wall_touches.len());
        touches.extend(chunks.iter().flat_map(|c| &c.touches));
        touches.extend(wall_touches.iter().map(|(t, _)| t));
        self.times.narrow += lap();
        // Two independent halves, side by side on the pool: each body gathers its forces and
        // moves (damping, kick, drift, rotation), while the contact list, the walls' loads and
        // the energy sums are made from the touches. Each half reads the touches and writes
        // its own fields, so the result does not depend on which runs first or on how many
        // threads share the work (one thread runs them one after the other).
        let World {
            bodies,
            walls,
            contacts,
            kept_buffer,
            alternates,
            energy,
            material,
            keep_structures,
            gravity,
            step,
            ..
        } = self;
        let (material, gravity) = (&*material, *gravity);
        let alpha = material.damping;
        let touches = &touches;
        let nb = bodies.len();
        let gather_kick = |(i, b): (usize, &mut Body), rows: &[(Vec<u32>, Vec<u32>); 2]| {
            if b.fixed {
                return None;
            }
            let (mut force, mut torque) = (gravity * b.mass, Vec3::zeros());
            // The body pairs' touches first, then the walls' (the order of `touches`).
            let [(pair_start, pair_ends), (wall_start, wall_ends)] = rows;
            let pair_row = &pair_ends[pair_start[i] as usize..pair_start[i + 1] as usize];
            let wall_row = &wall_ends[wall_start[i] as usize..wall_start[i + 1] as usize];
            let pairs = (pair_row.iter()).map(|&e| (touches[(e >> 1) as usize], Vec3::zeros(), e));
            let walls = (wall_row.iter()).map(|&e| {
                let (t, x) = &wall_touches[(e >> 1) as usize];
                (t, x.couple, e)
            });
            for (t, couple, e) in pairs.chain(walls) {
                let arm = (t.point - b.pos).cross(&t.force) + couple;
                if e & 1 == 0 {
                    force += t.force;
                    torque += arm;
                } else {
                    force -= t.force;
                    torque -= arm;
                }
            }
            // The body has not moved since it was posed.
            let omega = omegas[i];
            let (mut f, mut m) = (force, torque);
            let (df, dm) = (
                local_damping(&f, &b.vel, alpha),
                local_damping(&m, &omega, alpha),
            );
            f += df;
            m += dm;
            let v_old = b.vel;
            b.vel += f * (dt / b.mass);
            b.ang_mom += m * dt;
            // Damping dissipation: minus the work of the damping force over the step.
            let damping = -(df.dot(&(v_old + b.vel)) * 0.5 * dt + dm.dot(&omega) * dt);
            b.pos += b.vel * dt;
            let gravity_work = b.mass * gravity.dot(&b.vel) * dt;
            Some([force.norm(), damping, gravity_work, 0.0])
        };
        // Bodies in runs: kicked and moved one by one, then turned four at a time, then
        // their kinetic energy taken.
        let move_run = |(k, run): (usize, &mut [Body]),
                        rows: &[(Vec<u32>, Vec<u32>); 2]|
         -> Vec<Option<[f64; 4]>> {
            let at = k * MOVE_RUN;
            let mut terms: Vec<Option<[f64; 4]>> = (run.iter_mut().enumerate())
                .map(|(j, b)| gather_kick((at + j, b), rows))
                .collect();
            free_rotations(run, dt);
            for (t, b) in terms.iter_mut().zip(run.iter()) {
                if let Some(t) = t {
                    t[3] = b.kinetic_energy();
                }
            }
            terms
        };
        let mut move_bodies = || -> Vec<Option<[f64; 4]>> {
            // Forces in a fixed order: each body adds its contacts in the order of `touches`
            // (the order of a serial loop over them), on any number of threads. The rows are
            // made here, beside the other half's first, serial loop (alone they were 2.9 %
            // of a step of the 2000 I_P bed on 2 threads, the other thread idle).
            let pairs = (chunks.iter().flat_map(|c| &c.touching)).map(|&(a, b)| (b, Some(a)));
            let walls = wall_keys.iter().map(|k| (k.1, None));
            let rows = [ends_by_body(pairs, nb), ends_by_body(walls, nb)];
            let rows = &rows;
            let runs = bodies.chunks_mut(MOVE_RUN).enumerate().collect();
            let runs = spread(runs, par, |run| move_run(run, rows));
            runs.into_iter().flatten().collect()
        };
        let list_contacts = || {
            for w in walls.iter_mut() {
                w.clear_forces();
            }
            let mut wall_work = 0.0;
            // The chunks' sums in chunk order (fixed by the pairs, whatever the threads).
            let mut sums = Sums::default();
            for c in chunks.iter() {
                sums.merge(&c.sums);
            }
            let wall_contacts = parts[pair_parts..].iter().flat_map(|p| p.values());
            for (((t, x), c), key) in wall_touches.iter().zip(wall_contacts).zip(&wall_keys) {
                sums.add(c, t, material);
                if let Partner::Wall(w) = key.0 {
                    walls[w as usize].push(&-t.force, &x.node_weights);
                    wall_work += x.wall_work;
                }
            }
            let last_kept = contacts.take_kept();
            let old_parts = contacts.set_parts(parts);
            let mut retired = Vec::new();
            // The structures move on with their contacts (body pairs come first in key order).
            if *keep_structures {
                // The structures that stopped holding, for the alternates (after the bodies
                // have moved: their shapes are read then).
                let touched = chunks
                    .iter()
                    .flat_map(|c| c.touches.iter().zip(&c.touching));
                let pairs = touched.map(|(t, pair)| {
                    if let Some(old) = last_kept.get(t.at).filter(|_| t.retired) {
                        retired.push((*pair, old.to_structure()));
                    }
                    match &t.kept {
                        Found::Kept => Carry::Kept(t.at),
                        Found::New(s) => Carry::New(s.packed().words()),
                        Found::Alternate => (alternates.get(pair))
                            .map_or(Carry::None, |(_, s)| Carry::New(s.packed().words())),
                        Found::None => Carry::None,
                    }
                });
                // Then the walls' sets (their contacts come last in key order).
                let walls = wall_touches.iter().map(|(_, x)| match &x.found {
                    WallFound::Kept => Carry::Kept(x.at),
                    WallFound::New(w) => Carry::New(w),
                    WallFound::None => Carry::None,
                });
                let mut carry: Vec<Carry> = Vec::with_capacity(touches.len());
                carry.extend(pairs.chain(walls));
                let spare = std::mem::take(kept_buffer);
                *kept_buffer = contacts.keep(last_kept, &carry, spare, par);
            }
            energy.elastic = sums.elastic;
            energy.friction += sums.slip;
            energy.wall_work += wall_work;
            (sums.force / touches.len() as f64, old_parts, retired)
        };
        let (terms, (mean_contact_force, old_parts, retired)) = if par {
            rayon::join(move_bodies, list_contacts)
        } else {
            (move_bodies(), list_contacts())
        };
        // A structure that stopped holding becomes its pair's alternate (the one it replaces,
        // if any, is the structure that holds now: see `Found::Alternate`).
        for ((i, j), s) in retired {
            let shapes = [bodies[i as usize].shape, bodies[j as usize].shape];
            alternates.insert((i, j), (shapes, s));
        }
        if *step % ALTERNATES_PRUNED == 0 {
            alternates.retain(|&(i, j), _| contacts.contains_key(&(Partner::Body(i), j)));
        }
        let (mut kinetic, mut damping, mut gravity_work) = (0.0, 0.0, 0.0);
        let (mut free, mut net) = (0usize, 0.0);
        for [f, d, w, k] in terms.into_iter().flatten() {
            free += 1;
            net += f;
            damping += d;
            gravity_work += w;
            kinetic += k;
        }
        self.unbalanced = if self.contacts.is_empty() || free == 0 {
            f64::INFINITY
        } else {
            (net / free as f64) / mean_contact_force
        };
        self.energy.kinetic = kinetic;
        self.energy.damping += damping;
        self.energy.gravity_work += gravity_work;
        self.time += dt;
        self.step += 1;
        self.posed = posed;
        buffers.give_back(chunks, old_parts);
        self.buffers = buffers;
        self.times.integration += lap();
    }
}

/// Each body's contact ends as compressed rows, in the order of the touches: body `i`'s are
/// `ends[start[i]..start[i + 1]]`, each a touch index times 2, plus 1 for the body taking the
/// force with a minus sign (body A of a pair). `touches` gives each touch's body B and, for a
/// pair, body A.
fn ends_by_body(
    touches: impl Iterator<Item = (u32, Option<u32>)> + Clone,
    bodies: usize,
) -> (Vec<u32>, Vec<u32>) {
    let mut start = vec![0u32; bodies + 1];
    for (b, a) in touches.clone() {
        start[b as usize + 1] += 1;
        if let Some(a) = a {
            start[a as usize + 1] += 1;
        }
    }
    for i in 0..bodies {
        start[i + 1] += start[i];
    }
    let mut next = start.clone();
    let mut ends = vec![0u32; start[bodies] as usize];
    for (k, (b, a)) in touches.enumerate() {
        let mut put = |body: u32, minus: u32| {
            ends[next[body as usize] as usize] = (k as u32) << 1 | minus;
            next[body as usize] += 1;
        };
        put(b, 0);
        if let Some(a) = a {
            put(a, 1);
        }
    }
    (start, ends)
}

/// A chunk of the body pairs' touches, and the pairs (A, B) that touch, in the same order;
/// `owner`: the slot in [`Buffers`] of the thread that made it.
struct Chunk {
    touches: Vec<Touch>,
    touching: Vec<(u32, u32)>,
    /// The contacts, for the contact list (taken out before the step's end).
    part: Part,
    owner: usize,
    /// The touches' sums: force magnitudes, elastic and slip energies.
    sums: Sums,
}

/// Sums over touches, each added in the touches' order ([`Chunk::sums`]).
#[derive(Clone, Copy, Default)]
struct Sums {
    force: f64,
    elastic: f64,
    slip: f64,
}

impl Sums {
    fn add(&mut self, c: &Contact, t: &Touch, m: &Material) {
        self.force += t.force.norm();
        self.elastic += c.elastic_energy(m);
        self.slip += t.slip_energy;
    }

    fn merge(&mut self, other: &Sums) {
        self.force += other.force;
        self.elastic += other.elastic;
        self.slip += other.slip;
    }
}

/// The narrow phase's chunk buffers, kept between steps, one pool per thread (and one for a
/// thread outside the pool): each buffer goes back, emptied, to the thread that filled it.
/// Allocated and freed anew each step (40 of 60 KB on the 2000 I_P bed, half of them freed
/// across threads), a step took 1.03-1.06x as long on 2 threads. A thread's pool holds at most
/// as many buffers as it once filled in a step (2000 I_P bed: up to 40 of 63 KB each, about
/// 2.5 KiB per body at worst). Only speed depends on them: a clone starts empty.
#[derive(Default)]
struct Buffers(Vec<std::sync::Mutex<Pool>>);

/// A thread's buffers: touches and touching pairs, and parts of the contact list (those the
/// list had come back a step later: [`Contacts::set_parts`]).
#[derive(Default)]
struct Pool {
    touches: Vec<TouchBuffers>,
    parts: Vec<Part>,
}

/// A chunk's touches and touching pairs.
type TouchBuffers = (Vec<Touch>, Vec<(u32, u32)>);

/// A chunk's three buffers: its touches, its touching pairs and its part of the contact list.
type ChunkBuffers = (Vec<Touch>, Vec<(u32, u32)>, Part);

impl Buffers {
    /// This thread's slot: its index in the pool of `threads`, or `threads` outside it.
    fn slot(threads: usize) -> usize {
        rayon::current_thread_index().map_or(threads, |i| i.min(threads))
    }

    /// An empty pair of buffers for this thread's next chunk (see [`Buffers::give_back`]).
    fn take(&self, slot: usize) -> ChunkBuffers {
        let mut pool = self.0[slot].lock().unwrap_or_else(|e| e.into_inner());
        let (touches, touching) = pool.touches.pop().unwrap_or_default();
        let part = pool.parts.pop().unwrap_or_default();
        (touches, touching, part)
    }

    /// An empty part of the contact list for this thread (the walls' contacts).
    fn take_part(&self, slot: usize) -> Part {
        let mut pool = self.0[slot].lock().unwrap_or_else(|e| e.into_inner());
        let mut part = pool.parts.pop().unwrap_or_default();
        part.tag = slot;
        part
    }

    /// The chunks' buffers back to the threads that filled them, and the contact list's
    /// parts it no longer holds to the threads that filled those.
    fn give_back(&mut self, chunks: Vec<Chunk>, parts: Vec<Part>) {
        let last = self.0.len() - 1;
        for mut c in chunks {
            // Emptied here, while the touches are still in cache (emptied when next taken,
            // their drop read them back from memory: the 500 bed took 1.05-1.12x as long).
            c.touches.clear();
            c.touching.clear();
            let pool = self.0[c.owner].get_mut().unwrap_or_else(|e| e.into_inner());
            pool.touches.push((c.touches, c.touching));
        }
        for mut p in parts {
            p.clear();
            // A part made on a larger pool (or by hand) goes to the last slot.
            let pool = self.0[p.tag.min(last)].get_mut();
            pool.unwrap_or_else(|e| e.into_inner()).parts.push(p);
        }
    }
}

impl Clone for Buffers {
    fn clone(&self) -> Buffers {
        Buffers::default()
    }
}

impl std::fmt::Debug for Buffers {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Buffers({} pools)", self.0.len())
    }
}

/// Up to this many bytes of large hulls' vertices in all (the shapes', not the bodies'), their
/// bodies are posed lazily for contacts ([`Shape::pose_for_contacts`]): half this machine's
/// 1 MiB of L2 per core. Measured, 1 thread: nine Ab_3 templates are 160 KiB, and posing their
/// 500 bodies lazily took a step 0.77x the time; the peer's 500 distinct Ab_3 hulls are 9 MiB,
/// and lazily a step took 1.24x (their shapes' vertices, read scattered, were cache misses).
/// The choice is the scene's (its shapes), so restarts and thread counts agree.
const LAZY_HULLS_MAX_BYTES: usize = 512 * 1024;

/// Below this many bodies a step runs on one thread: waking the pool every step costs more
/// than the work (measured: 6 bodies spent 3.5 s of system time per second of work).
pub const PARALLEL_MIN_BODIES: usize = 64;

/// Whether a step of `bodies` bodies runs its loops on the thread pool: from
/// [`PARALLEL_MIN_BODIES`] on, and only with more than one thread (with one, handing each loop
/// to the pool's thread and waiting cost 15 to 45 % of a step of 200 to 500 bodies, much of it
/// in futex and sched_yield calls). Serial and parallel loops give the same bytes.
fn parallel(bodies: usize) -> bool {
    bodies >= PARALLEL_MIN_BODIES && rayon::current_num_threads() > 1
}

/// Runs `f`, a loop of steps, on a thread of rayon's pool (the caller waits), so that a step's
/// loops are handed to the pool's other threads directly instead of each through the pool's
/// queue to a sleeping thread and back (with the steps keeping the pool awake, `Awake`: 0.95x
/// the time of 1000 steps of the 2000 I_P bed on 2 threads). The results are the same wherever
/// the steps run.
pub fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

/// Keeps the pool's other threads looking for work through one step (until dropped): a step
/// hands out six loops, and between two of them a worker that found nothing for a few
/// microseconds went to sleep; this VM then took 30 to 45 us to wake it for the next loop
/// (measured: the second thread's first item of the posing loop, 2000 I_P bed), a fifth of
/// that loop. Each other thread of the pool runs one copy, which takes work while there is
/// some and gives the processor back to the scheduler while there is none; it ends with the
/// step, or after [`AWAKE_IDLE`] without work or [`AWAKE_MAX`] in all (a copy started inside
/// one of the step's own loops, or on a pool shared with other work, so holds a loop up for
/// a bounded time at most, never forever). Only speed depends on it.
struct Awake(std::sync::Arc<std::sync::atomic::AtomicBool>);

/// An [`Awake`] thread gives up after this long without work, or this long in all.
const AWAKE_IDLE: std::time::Duration = std::time::Duration::from_micros(200);
const AWAKE_MAX: std::time::Duration = std::time::Duration::from_millis(50);

impl Awake {
    fn new() -> Awake {
        use std::sync::atomic::Ordering;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stepper = rayon::current_thread_index();
        let end = stop.clone();
        rayon::spawn_broadcast(move |ctx| {
            if Some(ctx.index()) == stepper {
                return;
            }
            let born = std::time::Instant::now();
            let mut busy = born;
            while !end.load(Ordering::Acquire) {
                if rayon::yield_now() == Some(rayon::Yield::Executed) {
                    busy = std::time::Instant::now();
                } else if busy.elapsed() > AWAKE_IDLE || born.elapsed() > AWAKE_MAX {
                    return;
                } else {
                    std::thread::yield_now();
                }
            }
        });
        Awake(stop)
    }
}

impl Drop for Awake {
    fn drop(&mut self) {
        self.0.store(true, std::sync::atomic::Ordering::Release);
    }
}

/// `filter_map` over `items`, in parallel when `par`; the result is in item order either way.
fn filter_map_maybe_par<T: Sync, U: Send>(
    items: &[T],
    par: bool,
    f: impl Fn(&T) -> Option<U> + Sync + Send,
) -> Vec<U> {
    if par {
        items.par_iter().filter_map(f).collect()
    } else {
        items.iter().filter_map(f).collect()
    }
}

/// The 21 low bits of `x` spread to every third bit (bit `k` to bit `3 k`): one axis of a
/// Morton code.
fn spread_bits(x: u64) -> u64 {
    (0..21).fold(0, |acc, k| acc | ((x >> k) & 1) << (3 * k))
}

/// PFC local damping of a force (or moment) `f` against velocity `v`: `-alpha |f_i| sign(v_i)`.
fn local_damping(f: &Vec3, v: &Vec3, alpha: f64) -> Vec3 {
    if alpha == 0.0 {
        return Vec3::zeros();
    }
    Vec3::from_fn(|i, _| {
        if v[i] == 0.0 {
            0.0
        } else {
            -alpha * f[i].abs() * v[i].signum()
        }
    })
}

/// Advances the orientation of a free rigid rotor with world angular momentum `l` by `dt`:
/// symmetric splitting into rotations about the principal axes (1, 2, 3, 2, 1 with half steps
/// on the outer ones). Each sub-step is an exact rotation, so |L| is kept exactly.
pub fn free_rotation(rot: &mut UnitQuaternion<f64>, l: &Vec3, moments: &Vec3, dt: f64) {
    let mut turn = Turn::of(rot, l);
    for (axis, h) in SPLITTING {
        turn.sub_step(axis, h, moments, dt);
    }
    *rot = turn.orientation();
}

/// [`free_rotation`] of every free body of `bodies`, about its angular momentum, four at a
/// time: each sub-step's turn hangs on the last one's (a chain of some 80 cycles), and four
/// bodies' chains side by side keep the core busy (a body at a time, the rotation was two
/// thirds of the bodies' motion per step). The same numbers as one at a time.
pub fn free_rotations(bodies: &mut [Body], dt: f64) {
    for group in bodies.chunks_mut(4) {
        let mut turns: [Option<Turn>; 4] = [None; 4];
        for (t, b) in turns.iter_mut().zip(group.iter()) {
            *t = (!b.fixed).then(|| Turn::of(&b.rot, &b.ang_mom));
        }
        for (axis, h) in SPLITTING {
            for (t, b) in turns.iter_mut().zip(group.iter()) {
                if let Some(t) = t {
                    t.sub_step(axis, h, &b.moments, dt);
                }
            }
        }
        for (t, b) in turns.iter().zip(group.iter_mut()) {
            if let Some(t) = t {
                b.rot = t.orientation();
            }
        }
    }
}

/// Bodies posed together (an item of [`spread`]).
const POSE_BLOCK: usize = 64;

/// Bodies moved together ([`free_rotations`] turns them four at a time).
const MOVE_RUN: usize = 64;

/// The symmetric splitting of a free rotation into turns about the principal axes: (axis,
/// share of the step).
const SPLITTING: [(usize, f64); 5] = [(0, 0.5), (1, 0.5), (2, 1.0), (1, 0.5), (0, 0.5)];

/// A free rotation under way: the angular momentum in the body's frame and the orientation
/// quaternion's parts.
#[derive(Clone, Copy)]
struct Turn {
    pi: Vec3,
    w: f64,
    v: Vec3,
}

impl Turn {
    fn of(rot: &UnitQuaternion<f64>, l: &Vec3) -> Turn {
        let q = rot.quaternion();
        Turn {
            pi: rot.inverse_transform_vector(l),
            w: q.w,
            v: q.imag(),
        }
    }

    /// The turn about principal axis `axis` for a share `h` of the step:
    /// r = (cos theta/2, sin theta/2 e); the body's angular momentum turns back by theta in
    /// the plane of the other two axes, and the orientation becomes q r. Written out per axis
    /// (a general quaternion product and rotation, with libm's sine and cosine, cost more).
    #[inline(always)]
    fn sub_step(&mut self, axis: usize, h: f64, moments: &Vec3, dt: f64) {
        let Turn { pi, w, v } = self;
        let theta = pi[axis] / moments[axis] * h * dt;
        if theta == 0.0 {
            return;
        }
        let (s, c) = half_angle_sin_cos(0.5 * theta);
        let (cos, sin) = (c * c - s * s, 2.0 * s * c);
        let (b, d) = ((axis + 1) % 3, (axis + 2) % 3);
        (pi[b], pi[d]) = (cos * pi[b] + sin * pi[d], cos * pi[d] - sin * pi[b]);
        let mut cross = Vec3::zeros(); // v x e
        (cross[b], cross[d]) = (v[d], -v[b]);
        let along = v[axis];
        *v = *v * c + cross * s;
        v[axis] += *w * s;
        *w = *w * c - along * s;
    }

    /// The orientation, normalized.
    fn orientation(&self) -> UnitQuaternion<f64> {
        let norm = (self.w * self.w + self.v.norm_squared()).sqrt();
        UnitQuaternion::new_unchecked(nalgebra::Quaternion::from_parts(
            self.w / norm,
            self.v / norm,
        ))
    }
}

/// `(sin x, cos x)`: by their series for the small angles of a step's turn (to round-off
/// below 1e-2: the next terms are under 1e-21 of the sum), else libm's.
fn half_angle_sin_cos(x: f64) -> (f64, f64) {
    if x.abs() >= 1e-2 {
        return x.sin_cos();
    }
    // Multiplied by the reciprocals: a division in this chain costs as much as the rest.
    let x2 = x * x;
    let sin = x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0))));
    let cos = 1.0
        - x2 * 0.5
            * (1.0 - x2 * (1.0 / 12.0) * (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0))));
    (sin, cos)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{cube, cuboid};
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

    /// A proof's limit says it holds exactly when the bodies' travel since, in whole units,
    /// is below its spare distance (what `travelled` sums as floats, whose answer it may
    /// only make stricter), and never for an unknown reading, a NaN or zero spare distance.
    #[test]
    fn a_gap_limit_holds_exactly_while_the_travel_is_below_the_spare() {
        use crate::dem::shape::travelled;
        let gap = |travel: [Travel; 2], spare: f64| Gap {
            pair: (0, 1),
            proof: GapProof {
                axis: Vec3::x(),
                spare,
            },
            hints: PackedHints::of(&Hints::default()),
            travel,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(31);
        let mut held = 0;
        for _ in 0..100_000 {
            let g = [
                rng.random_range(0..1u64 << 50),
                rng.random_range(0..1u64 << 50),
            ];
            let units = rng.random_range(1..1u64 << 40);
            let spare = units as f64 * TRAVEL_UNIT;
            // Travels within a few units of the spare distance, either side.
            let d0 = rng.random_range(0..=units + 3);
            let d1 = (units + 3 - d0).saturating_sub(rng.random_range(0..7));
            let t = [g[0] + d0, g[1] + d1];
            let holds = Gap::holds(gap(g, spare).limit(), t[0], t[1]);
            assert_eq!(holds, d0 + d1 < units, "{g:?} {t:?} {units}");
            let moved = travelled(g[0], t[0]) + travelled(g[1], t[1]);
            assert!(moved >= spare || holds, "stricter than the sum of floats");
            held += usize::from(holds);
        }
        assert!(held > 10_000 && held < 90_000, "{held}");
        // A spare distance that is not a whole number of units: the travel must be below it.
        let g = gap([5, 7], 10.5 * TRAVEL_UNIT).limit();
        assert!(Gap::holds(g, 5 + 10, 7) && !Gap::holds(g, 5 + 11, 7));
        for spare in [0.0, -1.0, f64::NAN] {
            assert_eq!(gap([0, 0], spare).limit(), 0, "{spare}");
        }
        assert_eq!(gap([TRAVEL_UNKNOWN, 0], 1.0).limit(), 0);
        assert_eq!(gap([0, TRAVEL_UNKNOWN], 1.0).limit(), 0);
        // Out of range: rounded down, still a bound.
        let far = gap([u64::MAX - 9, 3], 1e9).limit();
        assert_eq!(far, u64::MAX);
        assert!(!Gap::holds(far, TRAVEL_UNKNOWN, 0) && !Gap::holds(far, 0, TRAVEL_UNKNOWN));
        assert!(Gap::holds(gap([1, 2], 1e9).limit(), 1 << 62, 1 << 62));
    }

    #[test]
    fn gap_proofs_follow_their_pairs_to_a_new_kept_list() {
        let gap = |(i, j): (u32, u32)| Gap {
            pair: (i, j),
            proof: GapProof {
                axis: Vec3::new(i as f64, j as f64, 0.0),
                spare: 1e-3,
            },
            hints: PackedHints::of(&Hints::default()),
            travel: [0; 2],
        };
        // The old list (0, 1) (0, 5) (2, 3) (2, 9) (4, 5) (7, 8), proofs for all but (2, 3).
        // (0, 5) has only a stale proof: its limit was set to 0 (a contact since).
        let slots: Vec<Option<Gap>> = [(0, 1), (0, 5), (2, 3), (2, 9), (4, 5), (7, 8)]
            .into_iter()
            .map(|p| (p != (2, 3)).then(|| gap(p)))
            .collect();
        let limits = (slots.iter())
            .map(|g| g.filter(|g| g.pair != (0, 5)).map_or(0, |g| g.limit()))
            .collect();
        let old = Separations {
            slots,
            limits,
            odometers: Vec::new(),
        };
        let listed = [(0, 0), (0, 5), (1, 2), (2, 3), (2, 9), (7, 8), (9, 9)];
        let new = old.clone().realigned(&listed);
        let axes: Vec<Option<Vec3>> = new.slots.iter().map(|g| g.map(|g| g.proof.axis)).collect();
        let expected: Vec<Option<Vec3>> = listed
            .iter()
            .map(|&p| [(2, 9), (7, 8)].contains(&p).then(|| gap(p).proof.axis))
            .collect();
        assert_eq!(axes, expected);
        assert!(Separations::default()
            .realigned(&listed)
            .slots
            .iter()
            .all(Option::is_none));
        let limits: Vec<Travel> = (new.slots.iter())
            .map(|g| g.map_or(0, |g| g.limit()))
            .collect();
        assert_eq!(new.limits, limits);
        assert!(old.realigned(&[]).slots.is_empty());
        // A slot is one cache line (it was 216 bytes with both bodies' poses).
        assert_eq!(std::mem::size_of::<Gap>(), 64);
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
        use super::super::wall::Wall;
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
        crate::dem::state::write_world(&w, &mut out).unwrap();
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
