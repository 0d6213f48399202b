//! A certified separation test for two convex point sets (the Gilbert-Johnson-Keerthi iteration
//! on their Minkowski difference `A - B`).
//!
//! Pairs whose bounding boxes overlap but whose bodies do not are the costliest thing the
//! narrow phase can meet: clipping finds nothing only after trying every face. GJK walks the
//! support points of `A - B` towards the origin and stops as soon as a direction `d` has
//! `max over A of d.x < min over B of d.x - margin`. That inequality is checked with the exact
//! supports, so a `true` answer is a certificate whatever the iteration did on the way; `false`
//! only means "not shown separated" (overlapping, touching within the margin, or the iteration
//! gave up), and the caller then does the exact overlap.

use crate::dem::shape::{Climb, Posed, Shape};
use crate::math::Vec3;
use nalgebra::Rotation3;

/// A convex point set for GJK: its points, and for a large hull the vertex graph to find a
/// support by climbing (see [`Climb`]) instead of scanning every point.
#[derive(Clone, Copy)]
pub struct Points<'a> {
    pub points: &'a [Vec3],
    /// The hull's vertex graph and the body's rotation (to start a climb from [`Climb::start`]).
    pub climb: Option<(&'a Climb, &'a Rotation3<f64>)>,
    /// A posed body whose vertices were left out ([`Posed::vertex`]): its points, computed
    /// when asked for (`points` is then empty).
    pub posed: Option<(&'a Shape, &'a Posed)>,
}

impl<'a> Points<'a> {
    /// The vertices of `p`, a posed `s`.
    pub fn posed(s: &'a Shape, p: &'a Posed) -> Points<'a> {
        Points {
            points: &p.vertices,
            climb: s.climb.as_ref().map(|c| (c, &p.rot)),
            posed: p.vertices.is_empty().then_some((s, p)),
        }
    }

    /// Point `i`.
    fn point(&self, i: usize) -> Vec3 {
        match self.posed {
            Some((s, p)) => p.vertex(s, i),
            None => self.points[i],
        }
    }

    /// How many points there are.
    fn len(&self) -> usize {
        match self.posed {
            Some((s, p)) => p.vertex_count(s),
            None => self.points.len(),
        }
    }

    /// The index of a point farthest along `d`; `hint` is where a climb starts (the last
    /// support: GJK's directions turn little) and is moved to the answer. On a convex hull a
    /// vertex no neighbour of which is higher is the highest, up to round-off: a climb can
    /// stop below the true support by ~1e-14 of the coordinates, far inside GJK's margin.
    fn support(&self, d: &Vec3, hint: &mut Option<usize>) -> usize {
        let points = self.points;
        let Some((climb, rot)) = self.climb else {
            let mut best = 0;
            let mut reach = d.dot(&points[0]);
            for (i, p) in points.iter().enumerate().skip(1) {
                let h = d.dot(p);
                if h > reach {
                    reach = h;
                    best = i;
                }
            }
            return best;
        };
        let from = hint.unwrap_or_else(|| climb.start(rot, d));
        let (at, _) = climb.ascend(from, |i| d.dot(&self.point(i)));
        *hint = Some(at);
        at
    }
}

/// Up to four points of `A - B`, kept without allocating.
#[derive(Clone, Copy, Default)]
struct Simplex {
    points: [Vec3; 4],
    len: usize,
}

impl Simplex {
    fn of(points: &[Vec3]) -> Simplex {
        let mut s = Simplex::default();
        s.points[..points.len()].copy_from_slice(points);
        s.len = points.len();
        s
    }

    fn points(&self) -> &[Vec3] {
        &self.points[..self.len]
    }

    fn push(&mut self, p: Vec3) {
        self.points[self.len] = p;
        self.len += 1;
    }
}

/// Most iterations before giving up (a polytope pair needs a handful).
const MAX_ITERATIONS: usize = 32;

/// True when a plane with normal `d` (from A towards B) leaves all of `a` at least `margin`
/// below all of `b`; `start` is the first direction tried (best: from A's centre to B's).
pub fn separated(a: &[Vec3], b: &[Vec3], start: &Vec3, margin: f64) -> bool {
    let (pa, pb) = (
        Points {
            points: a,
            climb: None,
            posed: None,
        },
        Points {
            points: b,
            climb: None,
            posed: None,
        },
    );
    let mut hints = Hints::default();
    a.is_empty() || b.is_empty() || separating_gap(pa, pb, start, margin, &mut hints).is_some()
}

/// Where the climbs of A's and B's supports start (climbing hulls only), and where they ended:
/// kept for the same pair's next test, whose supports then lie a step or two away.
pub type Hints = [Option<usize>; 2];

/// [`separated`] that also hands back the direction that proved the gap, and the gap: A lies
/// that far below B along the direction (more than `margin`). The direction is the best start
/// for the same pair's next test, a step later (bodies move little, so it usually proves the
/// gap again with one support evaluation). `None` when no gap above `margin` was proven. The
/// answer does not depend on `hints` (a climb from anywhere ends at a support).
pub fn separating_gap(
    a: Points,
    b: Points,
    start: &Vec3,
    margin: f64,
    hints: &mut Hints,
) -> Option<(Vec3, f64)> {
    if a.len() == 0 || b.len() == 0 {
        return None;
    }
    // The farthest point of A - B along d: max_A d.x - min_B d.x at once.
    let [hint_a, hint_b] = hints;
    let mut diff = |d: &Vec3| a.point(a.support(d, hint_a)) - b.point(b.support(&-d, hint_b));
    let mut d = if start.norm() > 0.0 && start.norm().is_finite() {
        *start
    } else {
        Vec3::x()
    };
    let mut simplex = Simplex::default();
    for _ in 0..MAX_ITERATIONS {
        let len = d.norm();
        if len == 0.0 || !len.is_finite() {
            return None;
        }
        let w = diff(&d);
        // Every point of A - B lies at most `reach` along d: A is below B by at least -reach.
        let reach = d.dot(&w) / len;
        if reach < -margin {
            return Some((d, -reach));
        }
        // With d = -v, v the nearest point found so far, the gap is between -reach and |v|:
        // once they meet it is known to be below the margin.
        if simplex.len > 0 && len + reach <= 1e-9 * len {
            return None;
        }
        simplex.push(w);
        match nearest(&mut simplex) {
            Some(v) => d = -v,
            None => return None, // the origin is inside (or on) the simplex
        }
    }
    None
}

/// Reduces `simplex` (1 to 4 points of `A - B`) to the smallest face nearest the origin and
/// returns the point of that face nearest the origin; `None` when the origin lies on it
/// (within round-off) or inside the tetrahedron.
fn nearest(simplex: &mut Simplex) -> Option<Vec3> {
    let (point, keep) = closest_on(simplex.points());
    let scale = simplex
        .points()
        .iter()
        .map(|p| p.norm())
        .fold(0.0, f64::max);
    *simplex = keep;
    if point.norm() <= 1e-14 * scale {
        None
    } else {
        Some(point)
    }
}

/// The point of the convex hull of `s` nearest the origin and the vertices of the smallest
/// face holding it (for a tetrahedron holding the origin: the origin and all four).
fn closest_on(s: &[Vec3]) -> (Vec3, Simplex) {
    match s.len() {
        1 => (s[0], Simplex::of(s)),
        2 => closest_on_segment(s[0], s[1]),
        3 => closest_on_triangle(s[0], s[1], s[2]),
        _ => closest_on_tetrahedron(s[0], s[1], s[2], s[3]),
    }
}

fn closest_on_segment(a: Vec3, b: Vec3) -> (Vec3, Simplex) {
    let ab = b - a;
    let denom = ab.norm_squared();
    if denom == 0.0 {
        return (a, Simplex::of(&[a]));
    }
    let t = -a.dot(&ab) / denom;
    if t <= 0.0 {
        (a, Simplex::of(&[a]))
    } else if t >= 1.0 {
        (b, Simplex::of(&[b]))
    } else {
        (a + ab * t, Simplex::of(&[a, b]))
    }
}

/// Nearest point of triangle abc to the origin (Ericson, Real-Time Collision Detection 5.1.5).
fn closest_on_triangle(a: Vec3, b: Vec3, c: Vec3) -> (Vec3, Simplex) {
    let (ab, ac) = (b - a, c - a);
    let (d1, d2) = (ab.dot(&-a), ac.dot(&-a));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Simplex::of(&[a]));
    }
    let (d3, d4) = (ab.dot(&-b), ac.dot(&-b));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Simplex::of(&[b]));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (a + ab * (d1 / (d1 - d3)), Simplex::of(&[a, b]));
    }
    let (d5, d6) = (ab.dot(&-c), ac.dot(&-c));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Simplex::of(&[c]));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (a + ac * (d2 / (d2 - d6)), Simplex::of(&[a, c]));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Simplex::of(&[b, c]));
    }
    let sum = va + vb + vc;
    if sum == 0.0 || !sum.is_finite() {
        // A degenerate (flat) triangle: the best of its edges.
        return [
            closest_on_segment(a, b),
            closest_on_segment(b, c),
            closest_on_segment(a, c),
        ]
        .into_iter()
        .min_by(|x, y| x.0.norm_squared().total_cmp(&y.0.norm_squared()))
        .expect("three edges");
    }
    let (v, w) = (vb / sum, vc / sum);
    (a + ab * v + ac * w, Simplex::of(&[a, b, c]))
}

/// Nearest point of tetrahedron abcd to the origin: the origin itself when inside, else the
/// nearest of its faces that the origin lies outside of.
fn closest_on_tetrahedron(a: Vec3, b: Vec3, c: Vec3, d: Vec3) -> (Vec3, Simplex) {
    // The origin is outside face (p, q, r) when it lies on the other side from the fourth
    // vertex s.
    let outside = |p: Vec3, q: Vec3, r: Vec3, s: Vec3| {
        let n = (q - p).cross(&(r - p));
        let (sign_o, sign_s) = (n.dot(&-p), n.dot(&(s - p)));
        sign_o * sign_s < 0.0
    };
    let faces = [(a, b, c, d), (a, c, d, b), (a, d, b, c), (b, d, c, a)];
    let mut best: Option<(Vec3, Simplex)> = None;
    for (p, q, r, s) in faces {
        if outside(p, q, r, s) {
            let cand = closest_on_triangle(p, q, r);
            if best
                .as_ref()
                .is_none_or(|b| cand.0.norm_squared() < b.0.norm_squared())
            {
                best = Some(cand);
            }
        }
    }
    best.unwrap_or((Vec3::zeros(), Simplex::of(&[a, b, c, d])))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cube_at(c: Vec3, h: f64) -> Vec<Vec3> {
        let mut out = Vec::new();
        for i in 0..8 {
            let s = |k: usize| if i >> k & 1 == 1 { h } else { -h };
            out.push(c + Vec3::new(s(0), s(1), s(2)));
        }
        out
    }

    #[test]
    fn cubes_apart_along_any_axis_are_separated() {
        let a = cube_at(Vec3::zeros(), 0.5);
        for (p, sep) in [
            (Vec3::new(1.1, 0.0, 0.0), true),
            (Vec3::new(0.9, 0.0, 0.0), false),
            (Vec3::new(1.05, 1.05, 1.05), true),
            (Vec3::new(0.95, 0.95, 0.95), false),
            (Vec3::new(0.0, -1.0 - 1e-6, 0.3), true),
            (Vec3::new(0.0, -1.0 + 1e-6, 0.3), false),
        ] {
            let b = cube_at(p, 0.5);
            // From a poor start direction, too.
            for start in [p, Vec3::new(0.0, 0.0, 1.0), -p] {
                assert_eq!(separated(&a, &b, &start, 1e-9), sep, "{p:?} from {start:?}");
            }
        }
    }

    #[test]
    fn touching_within_the_margin_is_not_claimed_separated() {
        let a = cube_at(Vec3::zeros(), 0.5);
        let b = cube_at(Vec3::new(1.0 + 1e-12, 0.0, 0.0), 0.5);
        assert!(!separated(&a, &b, &Vec3::x(), 1e-9));
        assert!(separated(&a, &b, &Vec3::x(), 1e-13));
    }

    #[test]
    fn edge_to_edge_separation_is_found() {
        // Two cubes turned 45 degrees about different axes, edges crossing with a small gap:
        // no face normal separates them, only the cross product of the edges.
        let turn = |v: Vec3, axis: usize| {
            let (c, s) = (
                std::f64::consts::FRAC_1_SQRT_2,
                std::f64::consts::FRAC_1_SQRT_2,
            );
            match axis {
                0 => Vec3::new(v.x, c * v.y - s * v.z, s * v.y + c * v.z),
                _ => Vec3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z),
            }
        };
        let a: Vec<Vec3> = cube_at(Vec3::zeros(), 0.5)
            .into_iter()
            .map(|v| turn(v, 0))
            .collect();
        let reach = 2.0 * 0.5 * std::f64::consts::SQRT_2;
        for (gap, sep) in [(1e-6, true), (-1e-6, false)] {
            let b: Vec<Vec3> = cube_at(Vec3::zeros(), 0.5)
                .into_iter()
                .map(|v| turn(v, 1) + Vec3::new(0.0, 0.0, reach + gap))
                .collect();
            assert_eq!(
                separated(&a, &b, &Vec3::new(0.3, 0.2, 1.0), 1e-9),
                sep,
                "gap {gap}"
            );
        }
    }
}
