//! The broad phase: the body pairs whose bounding boxes overlap, every step.
//!
//! A sweep and prune over all boxes costs about as much per step as it finds pairs for: on a
//! dense 5000-particle bed it was a fifth of a step, though the bodies had hardly moved. So the
//! sweep runs on boxes grown by a margin, and its list of pairs is kept while every body's box
//! stays inside its grown box: two boxes that overlap now then lie in grown boxes that overlap,
//! so their pair is on the list. Each step filters the list by the boxes of that step, and a
//! step that finds a box outside its grown one sweeps again. The pairs are the same either way
//! (exactly the pairs whose boxes overlap, ascending): the margin changes the cost, never the
//! result, and nothing of it is part of the state.

use crate::math::Vec3;
use rayon::prelude::*;

/// An axis-aligned box: (min corner, max corner).
pub type Aabb = (Vec3, Vec3);

/// How far each box is grown for the kept list, as a share of the box's largest side.
pub const MARGIN: f64 = 0.05;

/// The kept list of pairs and the grown boxes it was made from.
#[derive(Clone, Debug, Default)]
pub struct Broad {
    grown: Vec<Aabb>,
    listed: Vec<(u32, u32)>,
    /// The last sweep's order of the bodies (nearly sorted for the next sweep).
    order: Vec<u32>,
    /// How many times the list was made (a sweep), for the benchmark's report.
    pub sweeps: u64,
}

impl Broad {
    /// Pairs `(i, j)`, `i < j`, whose boxes overlap, ascending; in parallel when `par`.
    pub fn pairs(&mut self, boxes: &[Aabb], par: bool) -> Vec<(u32, u32)> {
        let touch = |&&(i, j): &&(u32, u32)| overlap(&boxes[i as usize], &boxes[j as usize]);
        let (listed, _) = self.candidates(boxes, par);
        if par {
            listed.par_iter().filter(touch).copied().collect()
        } else {
            listed.iter().filter(touch).copied().collect()
        }
    }

    /// The kept list of pairs as the last [`Broad::candidates`] left it.
    pub fn listed(&self) -> &[(u32, u32)] {
        &self.listed
    }

    /// Pairs `(i, j)`, `i < j`, ascending, among which are all whose boxes overlap: the kept
    /// list (swept again first when a box has left its grown box). The caller filters them by
    /// [`overlap`] where it reads the boxes anyway (the narrow phase: a pass of its own over
    /// the list cost 3 to 7 % of a step on the 2000 I_P bed). With it, whether the list is new
    /// (what the caller keeps per pair must then follow the pairs).
    pub fn candidates(&mut self, boxes: &[Aabb], par: bool) -> (&[(u32, u32)], bool) {
        let inside = |(b, g): (&Aabb, &Aabb)| (0..3).all(|k| g.0[k] <= b.0[k] && b.1[k] <= g.1[k]);
        let kept = self.grown.len() == boxes.len() && boxes.iter().zip(&self.grown).all(inside);
        if !kept {
            self.grown = boxes
                .iter()
                .map(|(lo, hi)| {
                    let m = Vec3::repeat(MARGIN * (hi - lo).max());
                    (lo - m, hi + m)
                })
                .collect();
            self.listed = sweep(&self.grown, &mut self.order, par);
            self.sweeps += 1;
        }
        (&self.listed, !kept)
    }
}

/// Whether two boxes overlap (touching counts).
pub fn overlap(a: &Aabb, b: &Aabb) -> bool {
    (0..3).all(|k| a.0[k] <= b.1[k] && b.0[k] <= a.1[k])
}

/// Pairs (i < j) whose boxes overlap, ascending: sweep and prune along the axis on which the
/// box centres spread most (z for a tall falling cloud, where x would pair every body with a
/// tenth of the others). `order` is the last sweep's order (nearly sorted again: cheap to
/// sort). Which axis is swept changes the cost, not the pairs.
pub fn sweep(boxes: &[Aabb], order: &mut Vec<u32>, par: bool) -> Vec<(u32, u32)> {
    if order.len() != boxes.len() {
        *order = (0..boxes.len() as u32).collect();
    }
    let n = boxes.len().max(1) as f64;
    let centre = |b: &Aabb| (b.0 + b.1) * 0.5;
    let mean = boxes.iter().map(centre).sum::<Vec3>() / n;
    let spread = boxes
        .iter()
        .map(|b| (centre(b) - mean).map(|c| c * c))
        .sum::<Vec3>();
    let s = spread.imax();
    let (t, u) = ((s + 1) % 3, (s + 2) % 3);
    order.sort_by(|&a, &b| {
        boxes[a as usize].0[s]
            .total_cmp(&boxes[b as usize].0[s])
            .then(a.cmp(&b))
    });
    // Each body against those after it along the axis, in blocks of the order (in parallel
    // when asked); the pairs come out sorted either way.
    const BLOCK: usize = 64;
    let order = &order[..];
    let block = |(k0, chunk): (usize, &[u32])| {
        let mut pairs = Vec::new();
        for (k, &i) in chunk.iter().enumerate() {
            let a = &boxes[i as usize];
            for &j in &order[k0 * BLOCK + k + 1..] {
                let b = &boxes[j as usize];
                if b.0[s] > a.1[s] {
                    break;
                }
                if a.0[t] <= b.1[t] && b.0[t] <= a.1[t] && a.0[u] <= b.1[u] && b.0[u] <= a.1[u] {
                    pairs.push((i.min(j), i.max(j)));
                }
            }
        }
        pairs
    };
    let mut pairs: Vec<(u32, u32)>;
    if par {
        pairs = order
            .par_chunks(BLOCK)
            .enumerate()
            .flat_map_iter(block)
            .collect();
        pairs.par_sort_unstable();
    } else {
        pairs = order.chunks(BLOCK).enumerate().flat_map(block).collect();
        pairs.sort_unstable();
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn brute_force(boxes: &[Aabb]) -> Vec<(u32, u32)> {
        let n = boxes.len() as u32;
        (0..n)
            .flat_map(|i| (i + 1..n).map(move |j| (i, j)))
            .filter(|&(i, j)| overlap(&boxes[i as usize], &boxes[j as usize]))
            .collect()
    }

    /// Boxes of sizes 1 to 4 in a 20 x 20 x 20 region, moving each step by up to `step` of a
    /// size, some also growing or shrinking (a rotating body's box).
    fn walk(seed: u64, n: usize, steps: usize, step: f64, par: bool) -> (usize, u64) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let mut boxes: Vec<Aabb> = (0..n)
            .map(|_| {
                let c = Vec3::from_fn(|_, _| rng.random_range(0.0..20.0));
                let h = Vec3::from_fn(|_, _| rng.random_range(0.5..2.0));
                (c - h, c + h)
            })
            .collect();
        let mut broad = Broad::default();
        let mut found = 0;
        for _ in 0..steps {
            for b in &mut boxes {
                let d = Vec3::from_fn(|_, _| rng.random_range(-step..step));
                let g = Vec3::from_fn(|_, _| rng.random_range(-step..step) * 0.5);
                *b = (b.0 + d - g, b.1 + d + g);
            }
            let pairs = broad.pairs(&boxes, par);
            assert_eq!(pairs, brute_force(&boxes));
            found += pairs.len();
        }
        (found, broad.sweeps)
    }

    #[test]
    fn the_kept_list_gives_exactly_the_overlapping_boxes_every_step() {
        for par in [false, true] {
            // Slow motion: the list is kept for many steps.
            let (found, sweeps) = walk(1, 300, 60, 1e-3, par);
            assert!(found > 1000, "too few pairs to test anything: {found}");
            assert!(
                sweeps < 10,
                "the list was made {sweeps} times in 60 slow steps"
            );
            // Fast motion: boxes leave their grown boxes, and the list is made again.
            let (_, sweeps) = walk(2, 300, 30, 0.2, par);
            assert!(sweeps > 20, "only {sweeps} sweeps for fast boxes");
        }
    }

    #[test]
    fn a_box_that_changes_count_or_grows_out_of_its_margin_sweeps_again() {
        let unit = |x: f64| (Vec3::new(x, 0.0, 0.0), Vec3::new(x + 1.0, 1.0, 1.0));
        let mut broad = Broad::default();
        assert_eq!(broad.pairs(&[unit(0.0), unit(1.5)], false), vec![]);
        // Growing within the margin of 5 %: the list is kept (and is empty).
        let grown = (Vec3::new(1.5 - 0.04, 0.0, 0.0), Vec3::new(2.5, 1.0, 1.0));
        assert_eq!(broad.pairs(&[unit(0.0), grown], false), vec![]);
        assert_eq!(broad.sweeps, 1);
        // Past it the boxes touch: a new sweep must find them.
        let touching = (Vec3::new(1.0, 0.0, 0.0), Vec3::new(2.5, 1.0, 1.0));
        assert_eq!(broad.pairs(&[unit(0.0), touching], false), vec![(0, 1)]);
        assert_eq!(broad.sweeps, 2);
        assert_eq!(
            broad.pairs(&[unit(0.0), unit(0.5), unit(0.9)], false),
            vec![(0, 1), (0, 2), (1, 2)]
        );
        assert_eq!(broad.sweeps, 3);
    }
}
