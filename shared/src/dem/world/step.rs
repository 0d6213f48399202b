//! One time step of the world: walls moved, bodies posed and paired, contact forces from the
//! overlaps, then each body's forces gathered and its motion integrated.

use super::{Body, NearSets, World};
use crate::dem::collision::broad::{overlap as overlap_boxes, Aabb, Broad};
use crate::dem::collision::gaps::{Gap, Odometer, PackedHints, Separations};
use crate::dem::collision::gjk::Hints;
use crate::dem::collision::overlap::{
    centre_line, gap_proof, overlap_kept, overlap_kept_or, Found, Overlap, WallFound,
};
use crate::dem::contacts::{Carry, ContactKey, Cursor, Part, Partner};
use crate::dem::integrate::{free_rotations, local_damping};
use crate::dem::law::{self, Contact, Material};
use crate::dem::membrane;
use crate::dem::parallel::{parallel, spread, Awake};
use crate::dem::shape::{Posed, Travel};
use crate::dem::wall::{FacetGrid, WallKind};
use crate::math::Vec3;

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

/// What the broad phase hands the narrow phase: the posed bodies, the facet walls' grids, the
/// gap proofs (realigned to the kept list of pairs), the per-body lists, the broad phase with
/// its list, and the chunk buffers.
struct Paired {
    posed: Vec<Posed>,
    grids: Vec<Option<FacetGrid>>,
    gaps: Separations,
    poses: Poses,
    broad: Broad,
    buffers: Buffers,
}

/// What the narrow phase hands the integration: the body pairs' chunks, the wall contacts'
/// touches, the contact list's parts (the pairs' first, `pair_parts` of them, then the walls')
/// and the wall contacts' keys.
struct Narrow {
    chunks: Vec<Chunk>,
    wall_touches: Vec<(Touch, WallExtra)>,
    parts: Vec<Part>,
    wall_keys: Vec<ContactKey>,
    pair_parts: usize,
    near_carry: Vec<NearCarry>,
}

/// What a wall contact hands back beside its [`Touch`] (kept apart, so that the touches,
/// written by one thread and read by the other, are a fifth smaller).
struct WallExtra {
    /// For facet walls: the share of the force each node carries.
    node_weights: Vec<(u32, f64)>,
    /// For a membrane: the nodes' pushes ([`crate::dem::wall::WallHit::node_pushes`]) and the
    /// contact's stiffness.
    node_pushes: Vec<(u32, Vec3)>,
    stiffness: f64,
    /// For a wall contact in separate spots: the moment of the spots' pushes about the
    /// contact point, on top of `point x force` ([`crate::dem::wall::WallHit::couple`] times `kn`).
    couple: Vec3,
    /// Work the partner's surface did on the body over the step, J: the mean of the last and
    /// this step's force over the surface's displacement (as the contact's stored work counts
    /// it).
    wall_work: f64,
    /// The wall set to keep ([`crate::dem::collision::overlap::overlap_half_space_kept`]), and the contact's
    /// place in the last list (where a kept set is).
    found: WallFound,
    at: usize,
}

/// A run of wall contacts' part of the contact list, their touches, and the facet sets of the
/// bodies near a facet wall that touched it not ([`NearCarry`]).
type WallChunk = (Part, Vec<(Touch, WallExtra)>, Vec<NearCarry>);

/// A facet set for [`World::near_sets`], by (wall, body): the one kept there (`None`), or new
/// words.
type NearCarry = ((u32, u32), Option<Vec<u32>>);

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

    /// Contact forces of one touching pair from its overlap, under `material`'s stiffness.
    /// `omega`: the angular velocity of the key's body; `va`, `omega_a`: the partner's
    /// velocity at the contact point and its angular velocity (a wall's: none); `last`: the
    /// contact of `key` last step, if any.
    #[allow(clippy::too_many_arguments)]
    fn touch(
        &self,
        material: &Material,
        key: ContactKey,
        omega: &Vec3,
        last: Option<&Contact>,
        o: &Overlap,
        (va, omega_a): (Vec3, Vec3),
        friction: f64,
    ) -> (Contact, Touch) {
        let b = &self.bodies[key.1 as usize];
        let (n, depth) = o.normal_depth();
        let point = o.centroid;
        let rel = b.velocity_with(omega, &point) - va;
        let spin = 0.5 * n.dot(&(b.spin_with(omega) + omega_a));
        let law = law::linear(
            material, self.dt, n, depth, point, rel, spin, last, friction,
        );
        let touch = Touch {
            force: law.force,
            point,
            slip_energy: law.slip_energy,
            kept: Found::None,
            retired: false,
            at: 0,
        };
        (law.contact, touch)
    }

    /// Advances the world by one time step `dt`: the walls move, the bodies are posed and
    /// paired ([`World::broad_phase`]), the touching pairs' and wall contacts' forces are
    /// found ([`World::narrow_phase`]), and each body gathers its forces and moves while the
    /// contact list and the energy audit are made ([`World::integrate`]).
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
        membrane::pin_velocities(&mut self.walls);
        for w in &mut self.walls {
            w.advance(dt);
        }
        let par = parallel(self.bodies.len());
        let _awake = par.then(Awake::new);
        let mut paired = self.broad_phase(par);
        self.times.broad += lap();
        let narrow = self.narrow_phase(&mut paired, par);
        self.times.narrow += lap();
        let Paired {
            posed,
            grids,
            gaps,
            poses,
            broad,
            mut buffers,
        } = paired;
        self.grids = grids;
        self.broad = broad;
        self.separations = gaps;
        let (chunks, old_parts) = self.integrate(narrow, &poses.omegas, par);
        self.move_membranes(par);
        self.posed = posed;
        buffers.give_back(chunks, old_parts);
        self.buffers = buffers;
        self.times.integration += lap();
    }

    /// Each membrane's nodes kicked by this step's forces (see [`membrane::kick`]), and their
    /// energy into the audit.
    fn move_membranes(&mut self, par: bool) {
        let (kinetic, elastic) = (
            &mut self.energy.membrane_kinetic,
            &mut self.energy.membrane_elastic,
        );
        *kinetic = 0.0;
        *elastic = 0.0;
        for k in 0..self.walls.len() {
            if self.walls[k].membrane.is_none() {
                continue;
            }
            let e = membrane::kick(&mut self.walls, k, self.dt, self.material.damping, par);
            self.energy.membrane_kinetic += e.kinetic;
            self.energy.membrane_elastic += e.elastic;
            self.energy.membrane_damping += e.damping;
            self.energy.pressure_work += e.pressure_work;
            self.energy.wall_work += e.wall_work;
        }
    }

    /// Poses every body and lists the pairs whose boxes may overlap, with the gap proofs
    /// realigned to that list and the facet walls' grids for this step.
    fn broad_phase(&mut self, par: bool) -> Paired {
        let mut posed = std::mem::take(&mut self.posed);
        // Facet walls' triangles by place, for this step's nodes and the largest body.
        let faceted = (self.walls.iter()).any(|w| matches!(w.kind, WallKind::Facets { .. }));
        let largest = (self.bodies.iter())
            .filter(|_| faceted)
            .map(|b| self.bounding_radius(b))
            .fold(0.0, f64::max);
        // The last step's grids while they fit the nodes (see `FacetGrid::fits`).
        let mut grids = std::mem::take(&mut self.grids);
        grids.resize_with(self.walls.len(), || None);
        for (wall, grid) in self.walls.iter().zip(&mut grids) {
            FacetGrid::refresh(grid, wall, largest);
        }
        let mut gaps = std::mem::take(&mut self.separations);
        if gaps.odometers.len() != self.bodies.len() {
            // Odometers anew (a new world, or bodies added or taken away): the readings kept
            // with the gap proofs and structures no longer compare with theirs.
            gaps = Separations::new(&self.bodies);
            self.contacts.take_kept();
            self.alternates.clear();
            self.near_sets.clear();
        }
        let poses = self.pose_all(&mut posed, &mut gaps.odometers, &grids);
        let mut broad = std::mem::take(&mut self.broad);
        let (pairs, swept) = broad.candidates(&poses.boxes, par);
        let mut buffers = std::mem::take(&mut self.buffers);
        buffers
            .0
            .resize_with(rayon::current_num_threads() + 1, Default::default);
        if swept || gaps.slots.len() != pairs.len() {
            gaps = gaps.realigned(pairs);
        }
        Paired {
            posed,
            grids,
            gaps,
            poses,
            broad,
            buffers,
        }
    }

    /// The contacts of this step: for each listed pair, a kept gap proof or a new one, or the
    /// overlap and the law's forces; then every body's contacts with the walls its box reaches.
    /// The gap proofs are updated in `paired`.
    fn narrow_phase(&self, paired: &mut Paired, par: bool) -> Narrow {
        let Paired {
            posed,
            grids,
            gaps,
            poses,
            broad,
            buffers,
        } = paired;
        let Poses {
            boxes,
            reach,
            travels,
            omegas,
        } = &*poses;
        let pairs = broad.listed();
        let threads = rayon::current_num_threads();
        let buffers_ref = &*buffers;
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
                &self.material,
                key,
                &omegas[j as usize],
                last,
                &o,
                (va, bi.spin_with(&omegas[i as usize])),
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
            let (mut touches, mut touching, mut terms, mut part) = buffers_ref.take(owner);
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
            // The energy sums' terms too, while each touch is in this core's cache (read from
            // the touches afterwards, those made by the other core took 2.4x as long).
            for ((pair, slot), limit) in pairs.iter().zip(slots).zip(limits) {
                if let Some((key, contact, t)) = narrow(pair, &mut at, (slot, limit)) {
                    terms.push(Sums::terms(&contact, &t, &self.material));
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
                terms,
            }
        };
        let this = self;
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
            let mut near = Vec::new();
            touches.extend((wall_pairs.iter()).filter_map(|&(i, w)| {
                let b = &this.bodies[i as usize];
                if b.fixed {
                    return None;
                }
                let wall = &this.walls[w as usize];
                let shape = &this.shapes[b.shape as usize];
                let key = (Partner::Wall(w), i);
                let grid = grids[w as usize].as_ref();
                // The set the contact kept, or for a body near a facet wall untouched last
                // step, the one kept for it there.
                let (last, kept, kept_near) = match this.contacts.seek(&mut at, &key) {
                    Some((c, kept)) => {
                        let kept = kept.filter(|_| this.keep_structures);
                        (Some(c), kept.map(|k| k.words()), false)
                    }
                    None => {
                        let kept = (this.keep_structures && grid.is_some())
                            .then(|| this.near_sets.get(&(w, i)))
                            .flatten();
                        (None, kept.map(Vec::as_slice), kept.is_some())
                    }
                };
                let radius = shape.radius * b.scale;
                let (hit, found) = wall.touch_kept(shape, &posed[i as usize], radius, kept, grid);
                let Some(hit) = hit else {
                    if this.keep_structures && grid.is_some() {
                        match found {
                            WallFound::Kept if kept_near => near.push(((w, i), None)),
                            WallFound::Kept => near.push(((w, i), kept.map(<[u32]>::to_vec))),
                            WallFound::New(words) => near.push(((w, i), Some(words))),
                            WallFound::None => {}
                        }
                    }
                    return None;
                };
                // A set kept among the near ones moves to the contact list.
                let found = match (found, kept) {
                    (WallFound::Kept, Some(words)) if kept_near => WallFound::New(words.to_vec()),
                    (found, _) => found,
                };
                let material = wall_material(wall, &this.material);
                let (mut contact, t) = this.touch(
                    &material,
                    key,
                    &omegas[i as usize],
                    last,
                    &hit.overlap,
                    (hit.velocity, Vec3::zeros()),
                    this.material.wall_friction,
                );
                let last_force =
                    last.map_or(Vec3::zeros(), |c| c.normal * c.normal_force + c.shear);
                let mut extra = WallExtra {
                    node_weights: hit.node_weights,
                    node_pushes: hit.node_pushes,
                    stiffness: material.kn,
                    couple: Vec3::zeros(),
                    wall_work: 0.5 * (last_force + t.force).dot(&hit.velocity) * this.dt,
                    found,
                    at: at.index(),
                };
                if hit.couple != Vec3::zeros() {
                    // The spots' moment does work as the body turns (the wall does not).
                    extra.couple = hit.couple * material.kn;
                    contact.potential -= extra.couple.dot(&omegas[i as usize]) * this.dt;
                }
                part.push(key, contact);
                Some((t, extra))
            }));
            (part, touches, near)
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
        let mut near_carry = Vec::new();
        for done in spread(items, par, work) {
            match done {
                Done::Pairs(c) => chunks.push(c),
                Done::Walls((part, touches, near)) => {
                    wall_parts.push(part);
                    wall_touches.extend(touches);
                    near_carry.extend(near);
                }
            }
        }
        let mut parts: Vec<Part> = (chunks.iter_mut())
            .map(|c| std::mem::take(&mut c.part))
            .collect();
        let wall_keys: Vec<ContactKey> = (wall_parts.iter())
            .flat_map(|p| p.keys().iter().copied())
            .collect();
        let pair_parts = parts.len();
        parts.extend(wall_parts);
        Narrow {
            chunks,
            wall_touches,
            parts,
            wall_keys,
            pair_parts,
            near_carry,
        }
    }

    /// Each body gathers its forces and moves (damping, kick, drift, rotation) while, beside
    /// it, the contact list, the walls' loads and the energy sums are made from the touches;
    /// the time advances. Gives back the chunks and the contact list's old parts, whose
    /// buffers go back to their threads.
    fn integrate(&mut self, narrow: Narrow, omegas: &[Vec3], par: bool) -> (Vec<Chunk>, Vec<Part>) {
        let Narrow {
            chunks,
            wall_touches,
            parts,
            wall_keys,
            pair_parts,
            near_carry,
        } = narrow;
        // The near bodies' facet sets: those kept moved over, the new ones added, the rest
        // (bodies that touch now, or left the wall) dropped.
        let mut near_sets = NearSets::with_capacity(near_carry.len());
        for (key, words) in near_carry {
            if let Some(words) = words.or_else(|| self.near_sets.remove(&key)) {
                near_sets.insert(key, words);
            }
        }
        self.near_sets = near_sets;
        let dt = self.dt;
        // Made to size: collected from the chunks, the list grew by doubling (serially).
        let pair_touches: usize = chunks.iter().map(|c| c.touches.len()).sum();
        let mut touches: Vec<&Touch> = Vec::with_capacity(pair_touches + wall_touches.len());
        touches.extend(chunks.iter().flat_map(|c| &c.touches));
        touches.extend(wall_touches.iter().map(|(t, _)| t));
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
            // The touches' terms one by one, in the touches' order: the sums do not depend on
            // where the chunks begin, which follows the broad phase's kept list (not part of
            // the state: a restart makes another), nor on the threads.
            let mut sums = Sums::default();
            for t in chunks.iter().flat_map(|c| &c.terms) {
                sums.add_terms(t);
            }
            let wall_contacts = parts[pair_parts..].iter().flat_map(|p| p.values());
            for (((t, x), c), key) in wall_touches.iter().zip(wall_contacts).zip(&wall_keys) {
                if let Partner::Wall(w) = key.0 {
                    let wall = &mut walls[w as usize];
                    sums.add(c, t, &wall_material(wall, material));
                    if x.node_pushes.is_empty() {
                        wall.push(&-t.force, &x.node_weights);
                    } else {
                        wall.push_membrane(&-t.force, x.stiffness, &x.node_weights, &x.node_pushes);
                    }
                    // A membrane's contacts are internal (see `membrane`).
                    if wall.membrane.is_none() {
                        wall_work += x.wall_work;
                    }
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
        (chunks, old_parts)
    }
}

/// The material a wall's contacts follow: the world's, with a membrane's own contact
/// stiffness ([`membrane::Sheet`]).
fn wall_material(wall: &crate::dem::wall::Wall, material: &Material) -> Material {
    match &wall.membrane {
        Some(m) => Material {
            kn: m.sheet.kn,
            ks: m.sheet.ks,
            ..*material
        },
        None => *material,
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
    /// Each touch's terms of the [`Sums`]: force magnitude, elastic and slip energies.
    terms: Vec<[f64; 3]>,
}

/// Sums over touches, each added in the touches' order ([`Chunk::sums`]).
#[derive(Clone, Copy, Default)]
struct Sums {
    force: f64,
    elastic: f64,
    slip: f64,
}

impl Sums {
    /// A touch's terms: its force's magnitude, elastic and slip energies.
    fn terms(c: &Contact, t: &Touch, m: &Material) -> [f64; 3] {
        [t.force.norm(), c.elastic_energy(m), t.slip_energy]
    }

    fn add(&mut self, c: &Contact, t: &Touch, m: &Material) {
        self.add_terms(&Sums::terms(c, t, m));
    }

    fn add_terms(&mut self, &[force, elastic, slip]: &[f64; 3]) {
        self.force += force;
        self.elastic += elastic;
        self.slip += slip;
    }
}

/// The narrow phase's chunk buffers, kept between steps, one pool per thread (and one for a
/// thread outside the pool): each buffer goes back, emptied, to the thread that filled it.
/// Allocated and freed anew each step (40 of 60 KB on the 2000 I_P bed, half of them freed
/// across threads), a step took 1.03-1.06x as long on 2 threads. A thread's pool holds at most
/// as many buffers as it once filled in a step (2000 I_P bed: up to 40 of 63 KB each, about
/// 2.5 KiB per body at worst). Only speed depends on them: a clone starts empty.
#[derive(Default)]
pub(super) struct Buffers(Vec<std::sync::Mutex<Pool>>);

/// A thread's buffers: touches and touching pairs, and parts of the contact list (those the
/// list had come back a step later: [`Contacts::set_parts`]).
#[derive(Default)]
struct Pool {
    touches: Vec<TouchBuffers>,
    parts: Vec<Part>,
}

/// A chunk's touches, touching pairs and their sums' terms.
type TouchBuffers = (Vec<Touch>, Vec<(u32, u32)>, Vec<[f64; 3]>);

/// A chunk's four buffers: its touches, its touching pairs, their terms and its part of the
/// contact list.
type ChunkBuffers = (Vec<Touch>, Vec<(u32, u32)>, Vec<[f64; 3]>, Part);

impl Buffers {
    /// This thread's slot: its index in the pool of `threads`, or `threads` outside it.
    fn slot(threads: usize) -> usize {
        rayon::current_thread_index().map_or(threads, |i| i.min(threads))
    }

    /// An empty pair of buffers for this thread's next chunk (see [`Buffers::give_back`]).
    fn take(&self, slot: usize) -> ChunkBuffers {
        let mut pool = self.0[slot].lock().unwrap_or_else(|e| e.into_inner());
        let (touches, touching, terms) = pool.touches.pop().unwrap_or_default();
        let part = pool.parts.pop().unwrap_or_default();
        (touches, touching, terms, part)
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
            c.terms.clear();
            let pool = self.0[c.owner].get_mut().unwrap_or_else(|e| e.into_inner());
            pool.touches.push((c.touches, c.touching, c.terms));
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

/// Bodies posed together (an item of [`spread`]).
const POSE_BLOCK: usize = 64;

/// Bodies moved together ([`free_rotations`] turns them four at a time).
const MOVE_RUN: usize = 64;
