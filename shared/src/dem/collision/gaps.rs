//! Gap proofs kept between steps: a pair proven apart stays apart while the two bodies' travel
//! since, read from per-body odometers, is below the proof's spare distance.

use crate::dem::collision::gjk::Hints;
use crate::dem::collision::overlap::GapProof;
use crate::dem::shape::{motion_bound, travel_after, Travel, TRAVEL_UNIT, TRAVEL_UNKNOWN};
use crate::dem::world::Body;
use crate::math::Vec3;
use nalgebra::UnitQuaternion;

/// Gap proofs, one slot per pair of the broad phase's kept list ([`Broad::candidates`]), in
/// its order: a step updates them in place. (Made anew each step, the list of the pairs proven
/// apart was copied forward whole, 2 MB a step on the 2000 I_P bed, most of it unchanged: 3 % of
/// a step's time in the copy alone.) A slot may hold a proof from any earlier step: whether it
/// still holds is checked by the bodies' travel since, every time it is used.
#[derive(Clone, Debug, Default)]
pub(crate) struct Separations {
    pub(crate) slots: Vec<Option<Gap>>,
    /// Per slot, the largest sum of the two bodies' odometer readings under which its proof
    /// holds ([`Gap::limit`]), or 0 for none: the one word a step reads for a pair proven
    /// apart. (The check read the 64-byte slot, which spans two cache lines as often as not:
    /// the slots of the 5000 I_P bed's ~56 000 pairs, 3.6 MB, were the step's most missed
    /// loads; the limits are 450 KB.) A slot whose limit is 0 holds no proof.
    pub(crate) limits: Vec<Travel>,
    /// Per body, where it was at the last step and how far its points may have travelled since
    /// the odometers were set: what the proofs are checked against.
    pub(crate) odometers: Vec<Odometer>,
}

/// A pair `(i, j)`, `i < j`, proven apart: the proof, the supports it ended on, and both bodies'
/// odometer readings when it was made. (It held both bodies' poses, 144 of its 216 bytes: on the
/// 5000 I_P bed 12 MB of slots a step, and their first reads were the step's most missed
/// loads.)
#[derive(Clone, Copy, Debug)]
pub(crate) struct Gap {
    pub(crate) pair: (u32, u32),
    pub(crate) proof: GapProof,
    pub(crate) hints: PackedHints,
    pub(crate) travel: [Travel; 2],
}

/// [`Hints`] in 8 bytes rather than 32 (`u32::MAX` for none): with them a gap slot is 64 bytes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct PackedHints(pub(crate) [u32; 2]);

impl Gap {
    /// The largest sum of the two bodies' odometer readings `t0 + t1` under which the proof
    /// holds: their travel since, `(t0 - g0) + (t1 - g1)` units, is then less than the spare
    /// distance `spare / TRAVEL_UNIT` (a power of two: exact), and the pair is apart. 0 (no
    /// sum is below it) when a reading was unknown or nothing is spare; rounded down where the
    /// sum would run out of range.
    pub(crate) fn limit(&self) -> Travel {
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
    pub(crate) fn holds(limit: Travel, t0: Travel, t1: Travel) -> bool {
        t0.saturating_add(t1) < limit
    }
}

impl PackedHints {
    pub(crate) fn of(hints: &Hints) -> PackedHints {
        PackedHints(hints.map(|h| h.map_or(u32::MAX, |k| k as u32)))
    }

    pub(crate) fn hints(&self) -> Hints {
        self.0.map(|h| (h != u32::MAX).then_some(h as usize))
    }
}

/// A body's odometer: where it was at the last step, and the sum of each step's motion bound
/// since the odometer was set, a bound on how far any of its points has moved since then.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Odometer {
    pub(crate) at: Placed,
    pub(crate) travel: Travel,
}

impl Odometer {
    /// Read for body `b`, bounding radius `radius` about its centroid: the travel since `at`
    /// added, and `at` moved to `b`.
    pub(crate) fn advance(&mut self, b: &Body, radius: f64) {
        self.travel = travel_after(self.travel, self.at.moved(b, radius));
        self.at = Placed::of(b);
    }
}

/// Where a body was, as far as its points are concerned.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Placed {
    pub(crate) pos: Vec3,
    pub(crate) rot: UnitQuaternion<f64>,
    pub(crate) scale: f64,
    pub(crate) shape: u32,
}

impl Placed {
    pub(crate) fn of(b: &Body) -> Placed {
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
    pub(crate) fn moved(&self, b: &Body, radius: f64) -> f64 {
        if b.scale != self.scale || b.shape != self.shape {
            return (b.pos - self.pos).norm() + radius;
        }
        motion_bound((&self.pos, &self.rot), (&b.pos, &b.rot), radius)
    }
}

impl Separations {
    /// Slots for a new kept list `listed` (ascending), each with its pair's proof from these
    /// slots, if any (theirs are ascending by pair too).
    pub(crate) fn realigned(self, listed: &[(u32, u32)]) -> Separations {
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
    pub(crate) fn in_force(&self) -> impl Iterator<Item = &Gap> {
        (self.slots.iter().zip(&self.limits))
            .filter_map(|(g, &limit)| g.as_ref().filter(|_| limit != 0))
    }

    /// No proofs, and an odometer for each of `bodies` set at zero.
    pub(crate) fn new(bodies: &[Body]) -> Separations {
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
    pub(crate) fn get(&self, pair: (u32, u32)) -> Option<&Gap> {
        self.in_force().find(|g| g.pair == pair)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::collision::gjk::Hints;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

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
}
