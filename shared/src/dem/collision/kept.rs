//! The overlap polyhedron by its structure, kept from one step to the next.
//!
//! At rest, 99.5 % of contacts keep the same overlap structure from one step to the next
//! (docs/models/contact.md). So instead of clipping faces every step, a contact keeps the list of
//! the overlap's corners, each named by what makes it:
//! - a vertex of one body inside the other, or
//! - an edge of one body crossing a face plane of the other,
//!
//! and, for each face of either body that bounds the overlap, the ring of corners around its
//! piece. A step recomputes only the corners (a vertex, or one edge-plane crossing each) and sums
//! the pieces ([`Structure::evaluate`]).
//!
//! **When the structure is right.** Each corner is checked at every evaluation: a vertex must lie
//! inside every face plane of the other body, and an edge must cross its plane with both ends
//! off it and the crossing inside every other plane of the other body, all by a margin
//! ([`MARGIN_REL`] x size). Against a large body (an Ab_3 hull, [`CLIMB_MIN`] vertices or more,
//! some 1 500 planes) the same holds by local checks: an edge's crossing must lie inside its
//! face's polygon (then it is on the body's surface), and a vertex inside the planes it was
//! nearer than [`NEAR_REL`] x size to when found, while the bodies have moved less since than
//! its clearance from all the others. A structure is only made ([`discover`]) when, besides,
//! each ring's consecutive corners share exactly one plane other than the ring's own, and that
//! plane has a ring too. Then each ring is the whole of its face inside the overlap (a convex polygon inside
//! another whose every edge lies on a supporting line of the other is the other), and the rings
//! close the surface. When a corner fails, the structure has changed (a corner crossed a plane)
//! and the pair goes back to [`discover`].
//!
//! **Same bytes either way.** A structure that passes the checks is the overlap's own (every
//! corner a vertex of it, robustly, by the margin), and [`discover`] from the same poses finds
//! that same structure, in the same canonical order (corners sorted, pieces by body then face,
//! each ring counter-clockwise from its lowest corner). The result is computed from the
//! structure in both cases, so keeping structures or not gives the same bytes, and a restart
//! (which keeps none) equals the uninterrupted run. Near-degenerate overlaps (a corner within the
//! margin of another plane, faces pressed flat on each other) have no structure: the clipping
//! construction of [`crate::dem::collision::overlap`] handles them, every step.

use crate::dem::collision::overlap::{set_bits, Acc, Overlap};
use crate::dem::shape::{travelled, Posed, Shape, Travel, CLIMB_MIN, TRAVEL_UNKNOWN};
use crate::math::Vec3;
use nalgebra::UnitQuaternion;

/// Corners closer than this fraction of the pair's size to a plane they are not on, or to the
/// end of their edge, are too close to a change of structure to be trusted to a kept one.
/// Round-off in a corner is ~1e-16 x size.
const MARGIN_REL: f64 = 1e-9;

/// A vertex corner inside a large body is checked against the planes it was nearer than this
/// fraction of the pair's size to when found, and against the others by the bodies' motion
/// since; when that motion uses up their clearance, the structure is renewed
/// ([`Packed::renewed`]). A near plane, too, is only checked once the motion since could have
/// used up the clearance it had. At 5e-3 the 5000 Ab_3 bed's structures had
/// 74 near planes each (144 of their ~350 words) and 16 500 clearances ran out in 1000 steps;
/// at 2.5e-3, 27 near planes and 41 000: 1.03x with each found again, and 1.03x more with
/// each renewed instead (both bodies' motion bounds counted from one pose); 26 -> 21 KiB per
/// particle. 1.25e-3, renewing, ran as fast.
const NEAR_REL: f64 = 2.5e-3;

/// A corner of the overlap polyhedron, by what makes it. `side` 0 is body A, 1 body B.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Corner {
    /// Vertex `i` of body `side`, inside the other body.
    Vertex { side: u8, i: u32 },
    /// The edge from vertex `i` to `j` (`i < j`) of body `side`, crossing face `face` of the
    /// other body.
    Edge { side: u8, i: u32, j: u32, face: u32 },
}

impl Corner {
    /// A number that orders corners as their derived order does (vertices first, then by
    /// side and the indices), compared in one instruction: sorting a structure's corners by
    /// the enum's fields was a tenth of finding an Ab_3 one.
    fn order(self) -> u128 {
        let (variant, side, i, j, face) = match self {
            Corner::Vertex { side, i } => (0u128, side, i, 0, 0),
            Corner::Edge { side, i, j, face } => (1, side, i, j, face),
        };
        variant << 104
            | u128::from(side) << 96
            | u128::from(i) << 64
            | u128::from(j) << 32
            | u128::from(face)
    }
}

/// The structure of one overlap: its corners (ascending) and the rings of its pieces, laid out
/// in one run of words ([`Packed`]) so that a contact list can keep all its structures in one
/// buffer, in contact order: evaluated in place, every step, they are read front to back
/// (kept as five allocations each, scattered over the heap, they made the narrow phase take 1.3
/// times as long on the 2000 I_P bed, waiting for memory).
#[derive(Clone, Debug, PartialEq)]
pub struct Structure {
    words: Vec<u32>,
}

/// A [`Structure`]'s words, read in place: a header of [`HEADER`] words (the counts of
/// corners, near planes, pieces and ring entries; the clearance; whether it has budgets),
/// where the bodies were when it was found ([`FOUND_AT`] words) and one budget per corner
/// (an `f32`), both only when some corner has a budget or the clearance is finite, then 2
/// words per corner, 1 per piece (its body, face and where its ring ends), the ring entries
/// two to a word (16 bits each) and last 2 words per near plane, which a step reads only the
/// first few of (see [`Packed::evaluate`]). Vertex and face indices take 15 bits
/// ([`INDEX_LIMIT`]). On the 5000 Ab_3 bed a structure had 581 words when it took 4 per
/// corner, 3 per piece and near plane and 1 per ring entry, with the near planes before the
/// pieces; now about 350, and 205 before the near planes.
#[derive(Clone, Copy, Debug)]
pub struct Packed<'a> {
    words: &'a [u32],
}

/// Words of the header: 4 counts, the clearance (2) and whether `found_at` and the budgets
/// follow (1 or 0).
const HEADER: usize = 4 + 2 + 1;

/// Shapes with this many vertices or faces or more have no structures (their indices would
/// not fit the 15 bits a structure gives them): their overlaps are clipped every step.
pub const INDEX_LIMIT: usize = 1 << 15;

/// Words of `found_at`: the two bodies' odometer readings ([`Posed::travel`]), 2 words each.
/// (They were the two poses, 32 words, 40 % of an I_P contact's structure.)
const FOUND_AT: usize = 4;

/// The parts of a structure, as [`discover`] makes them.
#[derive(Default)]
struct Parts {
    corners: Vec<Corner>,
    /// Per piece, ascending by (side, face): the body, its face, and where the piece's ring ends
    /// in `rings` (it starts where the last one ended).
    pieces: Vec<(u8, u32, u32)>,
    /// Positions in `corners`, counter-clockwise seen from outside the overlap.
    rings: Vec<u16>,
    /// For the vertex corners inside a large body: the planes of that body each was nearer
    /// than [`NEAR_REL`] x size to when found (checked at every step), as (corner, face)...
    near: Vec<(u16, u32, f32)>,
    /// ... and the least clearance (distance inside) they had from all the other planes, when
    /// found (those are covered by the motion since); infinite without such corners.
    clearance: f64,
    /// The bodies' odometers when it was found ([`Posed::travel`]; [`TRAVEL_UNKNOWN`] for
    /// none).
    found_at: [Travel; 2],
    /// Per corner, how far the bodies may move from `found_at` before it must be checked
    /// again ([`Pair::budget`], rounded down; 0: checked at every step).
    budgets: Vec<f32>,
}

/// Two posed bodies and the margin their corners are checked with.
pub struct Pair<'a> {
    shapes: [&'a Shape; 2],
    posed: [&'a Posed; 2],
    margin: f64,
    /// [`NEAR_REL`] x size.
    near: f64,
    /// Per body: large ([`CLIMB_MIN`] vertices or more). A corner is then checked against it
    /// locally: an edge's crossing inside the face's polygon, a vertex by its clearance when
    /// found against the motion since ([`Structure::near`]).
    large: [bool; 2],
}

impl<'a> Pair<'a> {
    /// `None` when a small shape (fewer than [`CLIMB_MIN`] vertices) does not have its face
    /// planes posed.
    pub fn new(sa: &'a Shape, a: &'a Posed, sb: &'a Shape, b: &'a Posed) -> Option<Pair<'a>> {
        let large = |s: &Shape| s.vertices.len() >= CLIMB_MIN;
        let posed = |s: &Shape, p: &Posed| large(s) || p.normals.len() == s.face_count();
        if !posed(sa, a) || !posed(sb, b) {
            return None;
        }
        let size = (a.hi - a.lo).norm().max((b.hi - b.lo).norm());
        Some(Pair {
            shapes: [sa, sb],
            posed: [a, b],
            margin: MARGIN_REL * size,
            near: NEAR_REL * size,
            large: [large(sa), large(sb)],
        })
    }

    /// World position of vertex `i` of body `side`.
    #[inline(always)]
    fn vertex(&self, side: u8, i: u32) -> Vec3 {
        self.posed[side as usize].vertex(self.shapes[side as usize], i as usize)
    }

    /// World plane of face `f` of body `side`.
    #[inline(always)]
    fn plane(&self, side: u8, f: u32) -> (Vec3, f64) {
        self.posed[side as usize].plane(self.shapes[side as usize], f as usize)
    }

    /// True when `p` is inside the plane of face `f` of body `side` by the margin.
    fn vertex_inside(&self, side: u8, f: u32, p: &Vec3) -> bool {
        self.inside_plane(&self.plane(side, f), p)
    }

    /// True when `p` is inside the plane `(n, d)` by the margin.
    fn inside_plane(&self, (n, d): &(Vec3, f64), p: &Vec3) -> bool {
        n.dot(p) - d < -self.margin
    }

    /// How far `p` (world) lies inside each face plane of body `side`, by a scan in the body's
    /// own frame over its shape's planes (posing all ~1 500 planes of an Ab_3 hull for it, a
    /// rotation each, was most of the cost of finding a large pair's structure; groups of
    /// planes facing away are bounded, not scanned: [`crate::dem::shape::Climb::clearances`]).
    /// Calls `near(f, inside)` for each face whose plane `p` may be nearer to than
    /// [`NEAR_REL`] x size (to round-off: the caller checks those in world coordinates, as
    /// [`Pair::vertex_inside`] will), with how far inside it `p` is less its round-off, and
    /// returns a lower bound on the least distance inside the others, less its round-off
    /// (infinite when there are none; for a large body the bound of each group of planes
    /// facing away, see [`crate::dem::shape::Climb::clearances`]). Distances of the frame change's
    /// round-off, ~1e-16 of the positions, are far inside the allowance of 1e-3 x the margin.
    fn far_clearance(&self, side: u8, p: &Vec3, mut near: impl FnMut(u32, f64)) -> f64 {
        let (s, posed) = (self.shapes[side as usize], self.posed[side as usize]);
        let local = posed.rot.inverse_transform_vector(&(p - posed.pos));
        let slack = 1e-3 * self.margin;
        let limit = self.near + slack;
        let Some(climb) = &s.climb else {
            // Small shapes have their planes posed, and few of them.
            let mut far = f64::INFINITY;
            for f in 0..s.face_count() as u32 {
                let (n, d) = self.plane(side, f);
                let inside = d - n.dot(p);
                if inside < limit {
                    near(f, inside - slack);
                } else {
                    far = far.min(inside);
                }
            }
            return far - slack;
        };
        climb.clearances(&local, posed.scale, limit, |f, inside| {
            near(f, inside - slack)
        }) - slack
    }

    /// Whether `p` (world, a vertex of the other body) is inside every face plane of the large
    /// body `side` by the margin, as a vertex corner is found: the planes it may be near
    /// ([`Pair::far_clearance`]) each checked as [`Pair::vertex_inside`] will check them, and
    /// passed to `near` with how far inside they are; then the clearance of the others, else
    /// `None`.
    fn inside_with_clearance(
        &self,
        side: u8,
        p: &Vec3,
        mut near: impl FnMut(u32, f64),
    ) -> Option<f64> {
        let mut inside = true;
        let far = self.far_clearance(side, p, |f, inside_by| {
            inside &= self.vertex_inside(side, f, p);
            near(f, inside_by);
        });
        inside.then_some(far)
    }

    /// A bound on how far any point of either body has moved since their odometers read
    /// `found_at` (the sum of the two travels since, [`Posed::travel`]); infinite when an
    /// odometer is missing.
    fn moved_since(&self, found_at: [Travel; 2]) -> f64 {
        (0..2)
            .map(|k| travelled(found_at[k], self.posed[k].travel.unwrap_or(TRAVEL_UNKNOWN)))
            .sum()
    }

    /// True when `p`, on the plane (normal `n`) of face `f` of body `side`, lies inside the
    /// face's polygon by the margin. On the posed vertices when the body has them; else in the
    /// body's own frame, on its shape's vertices (posing them for it, when a large hull's are
    /// posed as read, was most of the cost of a kept Ab_3 contact).
    fn in_face(&self, side: u8, f: u32, n: &Vec3, p: &Vec3) -> bool {
        self.on_face(side, f, n, p, |face, vs, n, p, inv| {
            let m = self.margin * inv;
            face_edges(face, vs, n, p)
                .all(|(inward, t)| t > 0.0 && t * t > m * m * inward.norm_squared())
        })
    }

    /// `test` of face `f` of body `side` (its corners, the vertices they index, its normal) and
    /// `p` (world, on the plane of normal `n`), with the inverse of the frame's unit in world
    /// lengths: on the posed vertices when the body has them (1); else in the body's own
    /// frame, on its shape's vertices and normal (one over the body's scale).
    #[inline(always)]
    fn on_face<R>(
        &self,
        side: u8,
        f: u32,
        n: &Vec3,
        p: &Vec3,
        test: impl FnOnce(&[u32], &[Vec3], Vec3, Vec3, f64) -> R,
    ) -> R {
        let (s, posed) = (self.shapes[side as usize], self.posed[side as usize]);
        let face = s.face(f as usize);
        if !posed.vertices.is_empty() {
            return test(face, &posed.vertices, *n, *p, 1.0);
        }
        // One division: the checks are by a margin far above the round-off this changes.
        let inv = 1.0 / posed.scale;
        let at = posed.rot.inverse_transform_vector(&(p - posed.pos)) * inv;
        test(face, &s.vertices, s.normals[f as usize], at, inv)
    }

    /// Where corner `c` is, or `None` when it is not robustly a corner of the overlap; with
    /// `checked` false, where it is, unchecked (its budget covers the motion since it was found:
    /// [`Pair::budget`]).
    // Inlined into the kept structures' loop, with the edge's crossing (a call per corner,
    // its answer through memory: 1.05-1.07x on the 5000 Ab_3 bed and the 2000 I_P bed, 2
    // threads; inlining `Pair::corner` too was 0.88-0.93x).
    #[inline(always)]
    fn corner_checked(&self, c: Corner, checked: bool) -> Option<Vec3> {
        if checked {
            return self.corner(c);
        }
        Some(match c {
            Corner::Vertex { side, i } => self.vertex(side, i),
            Corner::Edge { side, i, j, face } => self.edge_on_plane(side, i, j, face).crossing(),
        })
    }

    /// Edge `(i, j)` of body `side` against the plane of face `face` of the other body.
    #[inline(always)]
    fn edge_on_plane(&self, side: u8, i: u32, j: u32, face: u32) -> EdgeOnPlane {
        let (n, d) = self.plane(1 - side, face);
        let (vi, vj) = (self.vertex(side, i), self.vertex(side, j));
        EdgeOnPlane {
            normal: n,
            ends: [vi, vj],
            above: [n.dot(&vi) - d, n.dot(&vj) - d],
        }
    }

    /// How far the two bodies may move (the sum of their [`motion_bound`]s) from these poses
    /// before corner `c` (checked here by [`Pair::corner`]) may fail its checks: 0 when it is
    /// checked every step anyway (against a large body: a vertex inside one has its own
    /// budgets, see [`NEAR_REL`]). On the 2000 I_P bed at rest 95 % of vertex corners and 85 %
    /// of edge corners go unchecked (each check is a dot product with every plane of the other
    /// body). A vertex moves by at most the motion relative to the other body's
    /// planes; an edge's ends too, and its crossing of a plane at an angle, with ends `s_i`
    /// and `s_j` off it (`D = s_i - s_j`, edge length `L`), by at most
    /// `3 delta + L delta / (|D| - 2 delta)`, which is below `(3 + 2 L / |D|) delta` while
    /// `delta <= |D| / 4`; the crossing must then stay inside the other planes by the margin
    /// (against a large body, inside its face's polygon: the edges' lines in the face's plane).
    fn budget(&self, c: Corner) -> f64 {
        let m = self.margin;
        let slack = 1e-3 * m;
        let left = match c {
            Corner::Vertex { side, i } => {
                if self.large[1 - side as usize] {
                    return 0.0;
                }
                let v = self.vertex(side, i);
                self.clearance_within(1 - side, &v, u32::MAX) - m
            }
            Corner::Edge { side, i, j, face } => {
                let e = self.edge_on_plane(side, i, j, face);
                let ([vi, vj], [si, sj]) = (e.ends, e.above);
                let span = (si - sj).abs();
                let clear = if self.large[1 - side as usize] {
                    self.face_clearance(1 - side, face, &e.normal, &e.crossing())
                } else {
                    self.clearance_within(1 - side, &e.crossing(), face)
                };
                let length = (vj - vi).norm();
                (si.abs() - m)
                    .min(sj.abs() - m)
                    .min(0.25 * span)
                    .min((clear - m) / (3.0 + 2.0 * length / span))
            }
        };
        (left - slack).max(0.0)
    }

    /// How far `p`, on the plane (normal `n`) of face `f` of body `side`, lies inside the
    /// face's polygon: the least distance from its edges' lines (large bodies).
    fn face_clearance(&self, side: u8, f: u32, n: &Vec3, p: &Vec3) -> f64 {
        self.on_face(side, f, n, p, |face, vs, n, p, inv| {
            face_edges(face, vs, n, p).fold(f64::INFINITY, |least, (inward, t)| {
                least.min(t / inward.norm())
            }) / inv
        })
    }

    /// How far `p` is inside every face plane of body `side` but `skip` (small bodies).
    fn clearance_within(&self, side: u8, p: &Vec3, skip: u32) -> f64 {
        let posed = self.posed[side as usize];
        (posed.normals.iter().zip(&posed.offsets).enumerate())
            .filter(|&(k, _)| k as u32 != skip)
            .map(|(_, (n, d))| d - n.dot(p))
            .fold(f64::INFINITY, f64::min)
    }

    /// Where corner `c` is, or `None` when it is not robustly a corner of the overlap.
    fn corner(&self, c: Corner) -> Option<Vec3> {
        match c {
            Corner::Vertex { side, i } => {
                let v = self.vertex(side, i);
                // Inside a large body: see `Structure::near`.
                (self.large[1 - side as usize] || self.inside(1 - side, &v, u32::MAX)).then_some(v)
            }
            Corner::Edge { side, i, j, face } => {
                let e = self.edge_on_plane(side, i, j, face);
                let ([si, sj], m) = (e.above, self.margin);
                if !((si < -m && sj > m) || (si > m && sj < -m)) {
                    return None;
                }
                let p = e.crossing();
                let inside = if self.large[1 - side as usize] {
                    self.in_face(1 - side, face, &e.normal, &p)
                } else {
                    self.inside(1 - side, &p, face)
                };
                inside.then_some(p)
            }
        }
    }

    /// True when `p` is inside every face plane of body `side` but `skip` by the margin.
    fn inside(&self, side: u8, p: &Vec3, skip: u32) -> bool {
        let posed = self.posed[side as usize];
        let m = self.margin;
        posed
            .normals
            .iter()
            .zip(&posed.offsets)
            .enumerate()
            .all(|(k, (n, d))| k as u32 == skip || n.dot(p) - d < -m)
    }

    /// The face planes corner `c` lies on, as (side, face), ascending.
    fn planes(&self, c: Corner, out: &mut Vec<(u8, u32)>) {
        out.clear();
        match c {
            Corner::Vertex { side, i } => {
                let s = self.shapes[side as usize];
                out.extend(s.faces_at(i as usize).iter().map(|&f| (side, f)));
            }
            Corner::Edge { side, i, j, face } => {
                let s = self.shapes[side as usize];
                let at_j = s.faces_at(j as usize);
                out.extend(
                    s.faces_at(i as usize)
                        .iter()
                        .filter(|f| at_j.contains(f))
                        .map(|&f| (side, f)),
                );
                out.push((1 - side, face));
            }
        }
        out.sort_unstable();
    }
}

/// For each edge `(u, w)` of `face` (its corners in `vs`, counter-clockwise about the outward
/// normal `n`), from the last corner's round to the first: the edge's inward normal in the
/// plane, `n x (w - u)`, and `p`'s distance inside the edge's line times that normal's length.
#[inline(always)]
fn face_edges<'f>(
    face: &'f [u32],
    vs: &'f [Vec3],
    n: Vec3,
    p: Vec3,
) -> impl Iterator<Item = (Vec3, f64)> + 'f {
    let last = vs[face[face.len() - 1] as usize];
    face.iter().scan(last, move |u, &w| {
        let w = vs[w as usize];
        let inward = n.cross(&(w - *u));
        let t = inward.dot(&(p - *u));
        *u = w;
        Some((inward, t))
    })
}

/// An edge of one body against a face plane of the other: the plane's normal, the edge's ends
/// (world) and how far each lies above the plane.
struct EdgeOnPlane {
    normal: Vec3,
    ends: [Vec3; 2],
    above: [f64; 2],
}

impl EdgeOnPlane {
    /// Where the edge crosses the plane (its ends on either side).
    fn crossing(&self) -> Vec3 {
        let ([vi, vj], [si, sj]) = (self.ends, self.above);
        vi + (vj - vi) * (si / (si - sj))
    }
}

/// [`discover`]'s working lists, kept per thread between calls (made afresh, its two dozen
/// lists were a tenth of its time on the 5000 Ab_3 bed).
#[derive(Default)]
struct Finding {
    found: Vec<(Corner, Vec3)>,
    edges: Vec<(u32, u32)>,
    near: Vec<(Corner, u32, f64)>,
    ends: Vec<u32>,
    dist: Vec<f64>,
    /// Per end, which candidate planes it lies above: one bit per plane, `words` per end.
    above: Vec<u64>,
    at: Vec<Vec3>,
    spheres: Vec<(Vec3, f64)>,
    slab: [Vec<(Vec3, f64)>; 2],
    /// The planes each corner lies on, corner after corner, ascending within each, and where
    /// each corner's run ends.
    on_planes: Vec<(u8, u32)>,
    on_ends: Vec<u32>,
    buf: Vec<(u8, u32)>,
    /// As [`on_key`]s, which sort as (plane, corner) do.
    on: Vec<u64>,
    /// Where each plane's group (a run of `on`) ends.
    groups: Vec<u32>,
    ring: Vec<(f64, u16)>,
    parts: Parts,
}

thread_local! {
    static FINDING: std::cell::RefCell<Finding> = std::cell::RefCell::default();
}

/// A number that orders the directions `(x, y)` in the plane as their angle `atan2(y, x)` does,
/// up to the turn at +-pi (a ring is cyclic: it is rotated to its lowest corner after): from
/// -2 (towards -x, below) through 0 (+x) to 2 (towards -x, above). No `atan2` (2-3 % of the
/// time of finding an Ab_3 structure).
fn pseudo_angle(x: f64, y: f64) -> f64 {
    let l1 = x.abs() + y.abs();
    if l1 == 0.0 {
        return 0.0;
    }
    let turn = 1.0 - x / l1;
    if y < 0.0 {
        -turn
    } else {
        turn
    }
}

/// How many planes the ascending lists `a` and `b` share, `own` left out (a merge: the lists
/// are a corner's three to six planes).
fn shared_planes(a: &[(u8, u32)], b: &[(u8, u32)], own: (u8, u32)) -> usize {
    let (mut i, mut j, mut shared) = (0, 0, 0);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                shared += usize::from(a[i] != own);
                i += 1;
                j += 1;
            }
        }
    }
    shared
}

/// The structure of the overlap of `pair`, or `None` when it is near-degenerate (or empty).
/// `reach`: each body's vertices that can lie in the overlap; `faces`: each body's faces that can
/// bound it (for both, all of them will do; [`crate::dem::collision::overlap`] passes those meeting its slab).
pub fn discover(pair: &Pair, reach: [&[u32]; 2], faces: [&[u32]; 2]) -> Option<Structure> {
    let fits = |s: &Shape| s.vertices.len() < INDEX_LIMIT && s.face_count() < INDEX_LIMIT;
    if !pair.shapes.iter().all(|s| fits(s)) {
        return None;
    }
    FINDING.with_borrow_mut(|f| discover_with(pair, reach, faces, f))
}

fn discover_with(
    pair: &Pair,
    reach: [&[u32]; 2],
    faces: [&[u32]; 2],
    scratch: &mut Finding,
) -> Option<Structure> {
    let Finding {
        found,
        edges,
        near,
        ends,
        dist,
        above,
        at,
        spheres,
        slab,
        on_planes,
        on_ends,
        buf,
        on,
        groups,
        ring,
        parts,
    } = scratch;
    found.clear();
    near.clear();
    let mut clearance = f64::INFINITY;
    // The planes of each body's faces that meet the slab.
    for (side, planes) in slab.iter_mut().enumerate() {
        planes.clear();
        planes.extend(faces[side].iter().map(|&f| pair.plane(side as u8, f)));
    }
    for side in 0..2u8 {
        let s = pair.shapes[side as usize];
        let (others, planes) = (faces[1 - side as usize], &slab[1 - side as usize]);
        for &i in reach[side as usize] {
            let c = Corner::Vertex { side, i };
            let Some(p) = pair.corner(c) else {
                continue;
            };
            if pair.large[1 - side as usize] {
                // Checked here against every plane: the near ones with the test
                // `Pair::vertex_inside` puts to them later, the others by their distance, and
                // later by its clearance. First the faces that meet the slab: most vertices in
                // the slab fail one of those.
                if !planes.iter().all(|pl| pair.inside_plane(pl, &p)) {
                    continue;
                }
                let listed = near.len();
                let push = |f, inside_by| near.push((c, f, inside_by));
                let Some(far) = pair.inside_with_clearance(1 - side, &p, push) else {
                    near.truncate(listed);
                    continue;
                };
                clearance = clearance.min(far);
            }
            found.push((c, p));
        }
        edges.clear();
        for &f in faces[side as usize] {
            let fv = s.face(f as usize);
            for (k, &p) in fv.iter().enumerate() {
                let q = fv[(k + 1) % fv.len()];
                edges.push((p.min(q), p.max(q)));
            }
        }
        edges.sort_unstable();
        edges.dedup();
        // Each end's distance to each candidate plane, once, and on which side of it the end
        // lies, as bits: an edge is a candidate for a plane it crosses (the check in
        // `Pair::corner` decides), a set bit of its ends' words combined.
        ends.clear();
        ends.extend(edges.iter().flat_map(|&(i, j)| [i, j]));
        ends.sort_unstable();
        ends.dedup();
        let words = planes.len().div_ceil(64);
        dist.clear();
        above.clear();
        at.clear();
        for &v in ends.iter() {
            let v = pair.vertex(side, v);
            let row = dist.len();
            dist.extend(planes.iter().map(|(n, d)| n.dot(&v) - d));
            for chunk in dist[row..].chunks(64) {
                let bit = |(k, &d): (usize, &f64)| u64::from(d > 0.0) << k;
                above.push(chunk.iter().enumerate().map(bit).sum::<u64>());
            }
            at.push(v);
        }
        // Against a large body, an edge's crossing of a face plane far from the face's polygon
        // is no corner: a sphere about each face (padded far beyond round-off) rules most of
        // them out before the checks of `Pair::corner`, which would reject them.
        spheres.clear();
        if let Some(climb) = pair.large[1 - side as usize]
            .then(|| pair.shapes[1 - side as usize].climb.as_ref())
            .flatten()
        {
            let posed = pair.posed[1 - side as usize];
            spheres.extend(others.iter().map(|&f| {
                let (c, r) = climb.face_spheres[f as usize];
                let r = r * posed.scale + 1e3 * pair.margin;
                (posed.pos + posed.rot * (c * posed.scale), r * r)
            }));
        }
        let end = |v: u32| ends.binary_search(&v).unwrap_or_default();
        let row = |k: usize| &dist[k * planes.len()..(k + 1) * planes.len()];
        for &(i, j) in edges.iter() {
            let (ki, kj) = (end(i), end(j));
            let (di, dj) = (row(ki), row(kj));
            for w in 0..words {
                let crossed = above[ki * words + w] ^ above[kj * words + w];
                for k in set_bits(crossed).map(|b| 64 * w + b) {
                    if let Some((c, r2)) = spheres.get(k) {
                        let (vi, vj) = (at[ki], at[kj]);
                        let p = vi + (vj - vi) * (di[k] / (di[k] - dj[k]));
                        if (p - c).norm_squared() > *r2 {
                            continue;
                        }
                    }
                    let c = Corner::Edge {
                        side,
                        i,
                        j,
                        face: others[k],
                    };
                    if let Some(p) = pair.corner(c) {
                        found.push((c, p));
                    }
                }
            }
        }
    }
    found.sort_unstable_by_key(|&(c, _)| c.order());
    if found.len() < 4 || found.len() > usize::from(u16::MAX) {
        return None;
    }
    // Which planes each corner lies on, and the corners on each plane.
    on_planes.clear();
    on_ends.clear();
    on.clear();
    for (k, &(c, _)) in found.iter().enumerate() {
        pair.planes(c, buf);
        on.extend(buf.iter().map(|&pl| on_key(pl, k as u16)));
        on_planes.extend_from_slice(buf);
        on_ends.push(on_planes.len() as u32);
    }
    let planes_of = |k: u16| {
        let k = k as usize;
        let start = if k == 0 { 0 } else { on_ends[k - 1] as usize };
        &on_planes[start..on_ends[k] as usize]
    };
    on.sort_unstable();
    groups.clear();
    for k in 1..=on.len() {
        if k == on.len() || on[k] >> 16 != on[k - 1] >> 16 {
            groups.push(k as u32);
        }
    }
    let group = |g: usize| {
        let start = if g == 0 { 0 } else { groups[g - 1] as usize };
        &on[start..groups[g] as usize]
    };
    let Parts {
        corners,
        pieces,
        rings,
        near: near_words,
        budgets,
        ..
    } = parts;
    pieces.clear();
    rings.clear();
    for g in (0..groups.len()).map(group) {
        if g.len() < 3 {
            return None; // a face touching the overlap along an edge or at a point
        }
        let (side, face) = ((g[0] >> 48) as u8, (g[0] >> 16) as u32);
        let (n, _) = pair.plane(side, face);
        let at = |x: u64| found[usize::from(x as u16)].1;
        let mean = g.iter().map(|&x| at(x)).sum::<Vec3>() / g.len() as f64;
        let first = at(g[0]) - mean;
        let u = first - n * n.dot(&first);
        let w = n.cross(&u);
        ring.clear();
        ring.extend(g.iter().map(|&x| {
            let r = at(x) - mean;
            (pseudo_angle(r.dot(&u), r.dot(&w)), x as u16)
        }));
        ring.sort_unstable_by(|x, y| x.0.total_cmp(&y.0));
        let lowest = (0..ring.len()).min_by_key(|&k| ring[k].1).unwrap_or(0);
        ring.rotate_left(lowest);
        // Consecutive corners share one edge line: the ring's plane and exactly one other,
        // which bounds a piece of its own (every plane a corner lies on has a group, and a
        // group of fewer than three corners ends the search above).
        for (k, &(_, c1)) in ring.iter().enumerate() {
            let c2 = ring[(k + 1) % ring.len()].1;
            if shared_planes(planes_of(c1), planes_of(c2), (side, face)) != 1 {
                return None;
            }
        }
        rings.extend(ring.iter().map(|&(_, k)| k));
        if rings.len() > usize::from(u16::MAX) {
            return None; // the ring ends would not fit their 16 bits
        }
        pieces.push((side, face, rings.len() as u32));
    }
    corners.clear();
    corners.extend(found.iter().map(|&(c, _)| c));
    near_words.clear();
    near_words.extend(near.iter().map(|&(c, f, inside)| {
        let k = corners.binary_search(&c).unwrap_or_default() as u16;
        (k, f, f32_at_most(inside))
    }));
    budgets.clear();
    parts.clearance = clearance;
    Some(seal(pair, parts))
}

/// The structure of `parts` (corners, pieces, rings, and the near planes as found), with the
/// near planes put least clearance first and each corner's budget and `found_at` from
/// `pair`'s poses: the last step of [`discover`] and of [`Packed::renewed`].
fn seal(pair: &Pair, parts: &mut Parts) -> Structure {
    let at = |p: &Posed| p.travel.unwrap_or(TRAVEL_UNKNOWN);
    // Least first (see `Packed::evaluate`), ties by corner and face.
    (parts.near).sort_unstable_by(|x, y| x.2.total_cmp(&y.2).then((x.0, x.1).cmp(&(y.0, y.1))));
    parts.budgets.clear();
    (parts.budgets).extend(parts.corners.iter().map(|&c| f32_at_most(pair.budget(c))));
    parts.found_at = [at(pair.posed[0]), at(pair.posed[1])];
    Structure::pack(parts)
}

/// Plane `(side, face)` and corner `k` in one number, ordered as the pair: a plane's corners
/// are then a run of the sorted list. Sorting the pairs themselves took 3.3 times as long
/// (88 against 27 ms in 300 steps of the 5000 Ab_3 bed).
fn on_key((side, face): (u8, u32), k: u16) -> u64 {
    u64::from(side) << 48 | u64::from(face) << 16 | u64::from(k)
}

/// The greatest `f32` not above `x` (finite `x`): a clearance kept in one word, rounded so that
/// it is never more than the clearance.
fn f32_at_most(x: f64) -> f32 {
    let low = x as f32;
    if f64::from(low) <= x {
        low
    } else if low > 0.0 {
        f32::from_bits(low.to_bits() - 1)
    } else if low == 0.0 {
        -f32::from_bits(1)
    } else {
        f32::from_bits(low.to_bits() + 1)
    }
}

/// The two words of `x`.
pub(crate) fn split(x: f64) -> [u32; 2] {
    split_bits(x.to_bits())
}

/// The two words of 64 bits, low first.
pub(crate) fn split_bits(bits: u64) -> [u32; 2] {
    [bits as u32, (bits >> 32) as u32]
}

/// Words of a [`pose_words`] pose: 8 numbers of 2 words.
pub(crate) const POSE_WORDS: usize = 16;

/// Where a body is (centroid, orientation, scale), as [`POSE_WORDS`] words (a kept
/// wall set's pose), read back by [`pose_of`].
pub(crate) fn pose_words(
    pos: &Vec3,
    rot: &UnitQuaternion<f64>,
    scale: f64,
) -> impl Iterator<Item = u32> {
    let q = rot.quaternion().coords;
    [pos.x, pos.y, pos.z, q.x, q.y, q.z, q.w, scale]
        .into_iter()
        .flat_map(split)
}

/// The pose of the words [`pose_words`] gave.
pub(crate) fn pose_of(w: &[u32]) -> (Vec3, UnitQuaternion<f64>, f64) {
    let x = |k: usize| join(&w[2 * k..]);
    let q = nalgebra::Quaternion::new(x(6), x(3), x(4), x(5));
    (
        Vec3::new(x(0), x(1), x(2)),
        UnitQuaternion::new_unchecked(q),
        x(7),
    )
}

impl Structure {
    fn pack(p: &Parts) -> Structure {
        let budgets = p.budgets.iter().any(|&b| b > 0.0);
        let found_at = if p.clearance.is_finite() || budgets {
            FOUND_AT
        } else {
            0
        };
        let with_budgets = if found_at > 0 { p.corners.len() } else { 0 };
        let len = HEADER
            + found_at
            + with_budgets
            + 2 * p.corners.len()
            + p.pieces.len()
            + p.rings.len().div_ceil(2)
            + 2 * p.near.len();
        let mut w = Vec::with_capacity(len);
        let count = |n: usize| n as u32;
        w.extend([
            count(p.corners.len()),
            count(p.near.len()),
            count(p.pieces.len()),
            count(p.rings.len()),
        ]);
        w.extend(split(p.clearance));
        w.push(u32::from(found_at > 0));
        for &travel in p.found_at.iter().filter(|_| found_at > 0) {
            w.extend(split_bits(travel));
        }
        if found_at > 0 {
            let budget = |k: usize| p.budgets.get(k).copied().unwrap_or(0.0);
            w.extend((0..p.corners.len()).map(|k| budget(k).to_bits()));
        }
        // The indices are below INDEX_LIMIT (`discover`).
        for c in &p.corners {
            w.extend(match *c {
                Corner::Vertex { side, i } => [u32::from(side) << 16 | i, 0],
                Corner::Edge { side, i, j, face } => {
                    [(u32::from(side) | 2) << 16 | i, j << 16 | face]
                }
            });
        }
        w.extend(
            p.pieces
                .iter()
                .map(|&(side, face, end)| u32::from(side) << 31 | face << 16 | end),
        );
        w.extend(
            (p.rings.chunks(2))
                .map(|k| u32::from(k[0]) | u32::from(k.get(1).copied().unwrap_or(0)) << 16),
        );
        w.extend((p.near.iter()).flat_map(|&(k, f, c)| [u32::from(k) << 16 | f, c.to_bits()]));
        debug_assert_eq!(w.len(), len);
        Structure { words: w }
    }

    /// The words, to be read in place.
    pub fn packed(&self) -> Packed<'_> {
        Packed { words: &self.words }
    }

    /// [`Packed::evaluate`].
    pub fn evaluate(&self, pair: &Pair) -> Option<Overlap> {
        self.packed().evaluate(pair)
    }

    /// How many corners the overlap has.
    pub fn corner_count(&self) -> usize {
        self.words[0] as usize
    }
}

thread_local! {
    static CORNERS: std::cell::RefCell<Vec<Vec3>> = std::cell::RefCell::default();
    static RENEWING: std::cell::RefCell<Parts> = std::cell::RefCell::default();
}

/// The two odometer readings of `found_at`'s words.
fn travels(w: &[u32]) -> [Travel; 2] {
    [join_bits(w), join_bits(&w[2..])]
}

/// The number that [`split`] gave the words `w[0]`, `w[1]` of.
pub(crate) fn join(w: &[u32]) -> f64 {
    f64::from_bits(join_bits(w))
}

/// The 64 bits that [`split_bits`] gave the words `w[0]`, `w[1]` of.
pub(crate) fn join_bits(w: &[u32]) -> u64 {
    u64::from(w[0]) | u64::from(w[1]) << 32
}

/// A corner from its 2 words.
#[inline(always)]
fn corner_of(c: &[u32]) -> Corner {
    let (tag, i) = (c[0] >> 16, c[0] & 0xffff);
    let side = (tag & 1) as u8;
    if tag < 2 {
        Corner::Vertex { side, i }
    } else {
        Corner::Edge {
            side,
            i,
            j: c[1] >> 16,
            face: c[1] & 0xffff,
        }
    }
}

/// Entry `k` of the rings' words (two 16-bit entries to a word).
#[inline(always)]
fn ring_entry(rings: &[u32], k: usize) -> usize {
    (rings[k / 2] >> (16 * (k % 2)) & 0xffff) as usize
}

/// A packed structure's sections, split once (see [`Packed`] for the layout).
struct Sections<'a> {
    clearance: f64,
    found_at: &'a [u32],
    budgets: &'a [u32],
    corners: &'a [u32],
    near: &'a [u32],
    pieces: &'a [u32],
    rings: &'a [u32],
}

impl<'a> Packed<'a> {
    /// The words of a packed structure (as [`Packed::words`] gave them).
    pub fn new(words: &'a [u32]) -> Packed<'a> {
        Packed { words }
    }

    fn sections(&self) -> Sections<'a> {
        let w = self.words;
        let count = |k: usize| w[k] as usize;
        let clearance = join(&w[4..6]);
        let with = w[6] == 1;
        let (found_at, rest) = w[HEADER..].split_at(if with { FOUND_AT } else { 0 });
        let (budgets, rest) = rest.split_at(if with { count(0) } else { 0 });
        let (corners, rest) = rest.split_at(2 * count(0));
        let (pieces, rest) = rest.split_at(count(2));
        let (rings, near) = rest.split_at(count(3).div_ceil(2));
        debug_assert_eq!(near.len(), 2 * count(1));
        Sections {
            clearance,
            found_at,
            budgets,
            corners,
            near,
            pieces,
            rings,
        }
    }

    /// The overlap of `pair` from this structure, or `None` when it is no longer the overlap's
    /// (a corner failed its check).
    pub fn evaluate(&self, pair: &Pair) -> Option<Overlap> {
        self.evaluate_renewing(pair).map(|(o, _)| o)
    }

    /// [`Packed::evaluate`]; where the motion since has used up the clearance of the vertices
    /// inside a large body, those vertices are checked afresh against every plane, and if they
    /// pass the structure comes back renewed ([`Packed::renewed`]) with the overlap.
    pub fn evaluate_renewing(&self, pair: &Pair) -> Option<(Overlap, Option<Structure>)> {
        let s = self.sections();
        // The vertices inside a large body are still inside it by the margin while the bodies
        // have moved less than their clearance allows.
        let mut moved = f64::INFINITY;
        let mut renew = false;
        if !s.found_at.is_empty() {
            moved = pair.moved_since(travels(s.found_at));
            if s.clearance.is_finite() && moved >= s.clearance - pair.margin {
                // Every corner checked (no budget covers this motion either), and the
                // vertices afresh by `renewed`.
                (moved, renew) = (f64::INFINITY, true);
            }
        }
        let o = CORNERS.with_borrow_mut(|at| {
            at.clear();
            // A corner within its budget is where it is; the others are checked.
            let budget = |k: usize| {
                s.budgets
                    .get(k)
                    .map_or(0.0, |&b| f64::from(f32::from_bits(b)))
            };
            for (k, c) in s.corners.chunks_exact(2).enumerate() {
                at.push(pair.corner_checked(corner_of(c), moved >= budget(k))?);
            }
            // A near plane the vertex was farther inside than the margin plus the motion since
            // is still behind it: the list is by clearance, least first, so the rest are too.
            // (A structure to renew has its vertices checked afresh instead.)
            for n in s.near.chunks_exact(2).take_while(|_| !renew) {
                if moved + pair.margin < f64::from(f32::from_bits(n[1])) {
                    break;
                }
                // Near planes are listed for vertex corners only; the side is the corner's.
                let (k, f) = ((n[0] >> 16) as usize, n[0] & 0xffff);
                let side = (s.corners[2 * k] >> 16 & 1) as u8;
                if !pair.vertex_inside(1 - side, f, &at[k]) {
                    return None;
                }
            }
            let mut acc = Acc::default();
            let mut start = 0;
            for &piece in s.pieces {
                let end = (piece & 0xffff) as usize;
                let on_b = piece >> 31 == 1;
                let _ = acc.piece_by(end - start, |k| at[ring_entry(s.rings, start + k)], on_b);
                start = end;
            }
            let (volume, centroid) = acc.volume_centroid()?;
            Some(Overlap {
                volume,
                centroid,
                area_b: acc.area_b,
            })
        })?;
        if !renew {
            return Some((o, None));
        }
        Some((o, Some(self.renewed(pair, &s)?)))
    }

    /// This structure, whose corners have just passed their checks at `pair`'s poses but
    /// whose vertices inside a large body have used up their clearance, made again from
    /// these poses: each such vertex checked against every plane of the other body as
    /// [`discover`] checks it (`None` when one is not inside), its near planes and the
    /// clearance found afresh, and the budgets and `found_at` as [`discover`] makes them. The
    /// same words as [`discover`] gives from these poses, without its search (on the 5000 Ab_3
    /// bed, 41 000 clearances ran out in 1000 steps).
    fn renewed(&self, pair: &Pair, s: &Sections) -> Option<Structure> {
        RENEWING.with_borrow_mut(|parts| {
            parts.corners.clear();
            (parts.corners).extend(s.corners.chunks_exact(2).map(corner_of));
            parts.pieces.clear();
            (parts.pieces).extend(
                s.pieces
                    .iter()
                    .map(|&w| ((w >> 31) as u8, w >> 16 & 0x7fff, w & 0xffff)),
            );
            let entries = s.pieces.last().map_or(0, |&w| (w & 0xffff) as usize);
            parts.rings.clear();
            (parts.rings).extend((0..entries).map(|k| ring_entry(s.rings, k) as u16));
            parts.near.clear();
            parts.clearance = f64::INFINITY;
            for (k, &c) in parts.corners.iter().enumerate() {
                let Corner::Vertex { side, i } = c else {
                    continue;
                };
                if !pair.large[1 - side as usize] {
                    continue;
                }
                let (p, near) = (pair.vertex(side, i), &mut parts.near);
                let push = |f, inside_by| near.push((k as u16, f, f32_at_most(inside_by)));
                let far = pair.inside_with_clearance(1 - side, &p, push)?;
                parts.clearance = parts.clearance.min(far);
            }
            Some(seal(pair, parts))
        })
    }

    /// The structure of these words, owned.
    pub fn to_structure(&self) -> Structure {
        Structure {
            words: self.words.to_vec(),
        }
    }

    /// The words, to be copied (a contact list keeps them in one buffer).
    pub fn words(&self) -> &'a [u32] {
        self.words
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::collision::overlap::{overlap_kept, overlap_kept_or, overlap_parts, Found};
    use crate::dem::shape::{motion_bound, travel_after};
    use crate::geometry::mesh::cube;
    use crate::geometry::polygen::{generate, Params};
    use crate::math::unit_f64;
    use nalgebra::UnitQuaternion;
    use rand::{RngCore, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// I_P templates of 6, 9 and 14 faces, and a cube.
    fn shapes() -> Vec<Shape> {
        let mut out = vec![Shape::from_mesh(&cube(0.5)).unwrap()];
        for faces in [6, 9, 14] {
            let params = Params {
                faces,
                ..Default::default()
            };
            out.push(Shape::from_mesh(&generate(&params, 3, 0).unwrap().mesh).unwrap());
        }
        out
    }

    fn rotation(rng: &mut impl RngCore, angle: f64) -> UnitQuaternion<f64> {
        let mut u = || (unit_f64(rng.next_u64()) - 0.5) * 2.0 * angle;
        UnitQuaternion::from_euler_angles(u(), u(), u())
    }

    fn direction(rng: &mut impl RngCore) -> Vec3 {
        let mut u = || unit_f64(rng.next_u64()) - 0.5;
        Vec3::new(u(), u(), u()).normalize()
    }

    /// `s` posed at `pos`, `rot` with an odometer as the world keeps one: 0 at a first pose,
    /// else `from`'s reading plus the bound of the motion from it ([`motion_bound`]).
    fn on_odometer(
        s: &Shape,
        from: Option<&Posed>,
        pos: &Vec3,
        rot: &UnitQuaternion<f64>,
    ) -> Posed {
        let mut p = s.posed(pos, rot, 1.0);
        p.travel = Some(from.map_or(0, |f| {
            let moved = motion_bound((&f.pos, &f.orientation), (pos, rot), s.radius);
            travel_after(f.travel.unwrap(), moved)
        }));
        p
    }

    /// Random overlapping poses of two shapes: A at the origin, B along a random direction at a
    /// fraction `reach` of the sum of their radii (0.8 to 1: shallow to medium overlaps).
    fn poses(rng: &mut impl RngCore, count: usize) -> Vec<(usize, usize, Posed, Posed)> {
        let shapes = shapes();
        let mut out = Vec::new();
        while out.len() < count {
            let k = out.len();
            let (i, j) = (k % shapes.len(), (k / shapes.len()) % shapes.len());
            let a = on_odometer(&shapes[i], None, &Vec3::zeros(), &rotation(rng, 3.2));
            let reach =
                (0.55 + 0.45 * unit_f64(rng.next_u64())) * (shapes[i].radius + shapes[j].radius);
            let b = on_odometer(
                &shapes[j],
                None,
                &(direction(rng) * reach),
                &rotation(rng, 3.2),
            );
            if overlap_parts(&shapes[i], &a, &shapes[j], &b, &(b.pos - a.pos)).is_some() {
                out.push((i, j, a, b));
            }
        }
        out
    }

    /// [`Corner::order`] sorts as the derived order does, which `Structure`'s binary searches
    /// over its corners rely on: both kinds, both sides, indices up to `u32::MAX`.
    #[test]
    fn corner_order_is_the_derived_order() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut index = || match rng.next_u32() % 4 {
            0 => 0,
            1 => u32::MAX,
            _ => rng.next_u32() % 1000,
        };
        let corners: Vec<Corner> = (0..400)
            .map(|k| match k % 3 {
                0 => Corner::Vertex {
                    side: (k % 2) as u8,
                    i: index(),
                },
                _ => Corner::Edge {
                    side: (k / 3 % 2) as u8,
                    i: index(),
                    j: index(),
                    face: index(),
                },
            })
            .collect();
        for a in &corners {
            for b in &corners {
                assert_eq!(a.order().cmp(&b.order()), a.cmp(b), "{a:?} against {b:?}");
            }
        }
    }

    #[test]
    fn the_structure_gives_the_clipped_overlap() {
        let shapes = shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let mut structured = 0;
        let all = poses(&mut rng, 2000);
        for (t, (i, j, a, b)) in all.iter().enumerate() {
            let (sa, sb) = (&shapes[*i], &shapes[*j]);
            let axis = b.pos - a.pos;
            let (clipped, _) = overlap_parts(sa, a, sb, b, &axis).unwrap();
            let Some(pair) = Pair::new(sa, a, sb, b) else {
                panic!("small shapes have a pair");
            };
            let Some(s) = discover_whole(&pair) else {
                continue;
            };
            structured += 1;
            let o = s.evaluate(&pair).expect("a discovered structure evaluates");
            let size = 2.0 * sa.radius.max(sb.radius);
            assert!(
                (o.volume - clipped.volume).abs() <= 1e-12 * crate::math::cube(size)
                    && (o.centroid - clipped.centroid).norm() <= 1e-9 * size
                    && (o.area_b - clipped.area_b).norm() <= 1e-12 * size * size,
                "pose {t}: structure {o:?}, clipped {clipped:?}"
            );
            // The culled candidates of the engine find the same structure as all of them.
            let (kept, found) = overlap_kept(sa, a, sb, b, &axis, None, true).unwrap();
            assert_eq!(found, Found::New(s), "pose {t}");
            assert_eq!(kept.volume, o.volume, "pose {t}");
        }
        // Random poses are not degenerate: nearly every one has a structure.
        assert!(
            structured > all.len() * 98 / 100,
            "{structured} of {}",
            all.len()
        );
    }

    /// [`discover`] with every vertex and face of both bodies.
    fn discover_whole(pair: &Pair) -> Option<Structure> {
        let [sa, sb] = pair.shapes;
        discover(pair, [&all(sa), &all(sb)], [&faces(sa), &faces(sb)])
    }

    #[test]
    fn a_kept_structure_gives_the_same_bits_as_a_fresh_one() {
        // B moves a little from where its structure was found: kept or found again, the
        // overlap is the same to the bit, and both ways are taken (the structure still holds,
        // or a corner crossed a plane and it is found again).
        let shapes = shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(12);
        let (mut held, mut changed) = (0, 0);
        for (t, (i, j, a, b)) in poses(&mut rng, 1500).iter().enumerate() {
            let (sa, sb) = (&shapes[*i], &shapes[*j]);
            let Some((_, Found::New(s))) = overlap_kept(sa, a, sb, b, &(b.pos - a.pos), None, true)
            else {
                continue;
            };
            let step = sb.radius * 10f64.powf(-4.0 + 3.0 * unit_f64(rng.next_u64()));
            let q =
                rotation(&mut rng, step / sb.radius) * UnitQuaternion::from_rotation_matrix(&b.rot);
            let moved = on_odometer(sb, Some(b), &(b.pos + direction(&mut rng) * step), &q);
            let axis = moved.pos - a.pos;
            let fresh = overlap_kept(sa, a, sb, &moved, &axis, None, true);
            let kept = overlap_kept(sa, a, sb, &moved, &axis, Some(s.packed()), true);
            assert_eq!(
                fresh.as_ref().map(|f| f.0),
                kept.as_ref().map(|k| k.0),
                "pose {t}"
            );
            match Pair::new(sa, a, sb, &moved).and_then(|p| s.evaluate(&p)) {
                Some(_) => held += 1,
                None => changed += 1,
            }
        }
        assert!(
            held > 300 && changed > 100,
            "held {held}, changed {changed}"
        );
    }

    #[test]
    fn clearances_kept_in_one_word_round_down() {
        for x in [0.1, 1e-7, 3.3e-5, -2.5e-6, 0.0, 1.0 + 1e-12, 7e-46, -7e-46] {
            let low = f32_at_most(x);
            assert!(f64::from(low) <= x, "{x}");
            assert!(
                f64::from(low) >= x - x.abs() * 1.2e-7 - 1.5e-45,
                "{x}: {low}"
            );
        }
    }

    /// A corner's budget ([`Pair::budget`]) is a motion under which its checks still pass:
    /// B moved and turned (straight at a vertex corner from its nearest plane, or at random) by
    /// nine tenths of a corner's budget, by the bodies' motion bound, leaves it a corner.
    #[test]
    fn a_corner_moved_within_its_budget_passes_its_checks() {
        let shapes = shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(21);
        let (mut tried, mut budgets) = (0, 0);
        for (i, j, a, b) in poses(&mut rng, 600) {
            let (sa, sb) = (&shapes[i], &shapes[j]);
            let Some(pair) = Pair::new(sa, &a, sb, &b) else {
                continue;
            };
            let Some(s) = discover_whole(&pair) else {
                continue;
            };
            for c in corners_of(&s) {
                let budget = pair.budget(c);
                tried += 1;
                if budget <= 0.0 {
                    continue;
                }
                budgets += 1;
                for k in 0..4 {
                    // Split the budget between a shift and a turn of B, as the bound counts them.
                    // The bound is |shift|_1 + 2 r |sin(angle / 2) axis|_1.
                    let share = if k == 0 {
                        1.0
                    } else {
                        unit_f64(rng.next_u64())
                    };
                    // First straight at the nearest of B's planes to a vertex corner of A.
                    let d = match c {
                        Corner::Vertex { side: 0, i } if k == 0 => {
                            let v = a.vertex(sa, i as usize);
                            let near = (0..sb.face_count())
                                .min_by(|&f, &g| {
                                    let gap = |f: usize| b.offsets[f] - b.normals[f].dot(&v);
                                    gap(f).total_cmp(&gap(g))
                                })
                                .unwrap();
                            -b.normals[near]
                        }
                        _ => direction(&mut rng),
                    };
                    moved_within_budget(&mut rng, (sa, &a), (sb, &b), c, budget, (d, share));
                }
            }
        }
        assert!(
            budgets > tried / 2,
            "{budgets} of {tried} corners had budgets"
        );
    }

    /// B shifted along `d` and turned about a random axis by nine tenths of `budget`, `share`
    /// of it by the shift (the bound counts `|shift| + 2 r |sin(angle / 2) axis|`): the
    /// motion bound is within the budget and corner `c` is still a corner.
    fn moved_within_budget(
        rng: &mut impl RngCore,
        (sa, a): (&Shape, &Posed),
        (sb, b): (&Shape, &Posed),
        c: Corner,
        budget: f64,
        (d, share): (Vec3, f64),
    ) {
        let shift = d * (0.9 * budget * share / d.norm());
        let axis = direction(rng);
        let sine = 0.9 * budget * (1.0 - share) / (2.0 * sb.radius * axis.norm());
        let turn = UnitQuaternion::new(axis * (2.0 * sine.min(1.0).asin()));
        let moved = on_odometer(sb, Some(b), &(b.pos + shift), &(turn * b.orientation));
        let now = Pair::new(sa, a, sb, &moved).unwrap();
        let bound = now.moved_since([a.travel.unwrap(), b.travel.unwrap()]);
        assert!(bound <= budget, "motion {bound} over the budget {budget}");
        assert!(
            now.corner(c).is_some(),
            "{c:?} failed within its budget {budget}"
        );
    }

    /// The packed words give back every part, with indices up to the last one that fits
    /// ([`INDEX_LIMIT`]) and an odd number of ring entries (the last word half used).
    #[test]
    fn packed_words_give_back_indices_up_to_the_limit() {
        let top = (INDEX_LIMIT - 1) as u32;
        let corners = vec![
            Corner::Vertex { side: 0, i: 7 },
            Corner::Vertex { side: 1, i: top },
            Corner::Edge {
                side: 0,
                i: 3,
                j: top,
                face: top,
            },
            Corner::Edge {
                side: 1,
                i: top - 1,
                j: top,
                face: 0,
            },
        ];
        let parts = Parts {
            corners: corners.clone(),
            pieces: vec![(0, top, 3), (1, 5, 5)],
            rings: vec![0, 2, 3, 1, 3],
            near: vec![(1, top, 0.25), (0, 9, 0.5)],
            clearance: 0.125,
            budgets: vec![0.0, 1.5, 2.5, 0.0],
            ..Parts::default()
        };
        let s = Structure::pack(&parts);
        assert_eq!(corners_of(&s), corners);
        let w = s.packed().sections();
        assert_eq!(w.clearance, 0.125);
        assert_eq!(w.pieces, [top << 16 | 3, 1 << 31 | 5 << 16 | 5]);
        let rings: Vec<usize> = (0..5).map(|k| ring_entry(w.rings, k)).collect();
        assert_eq!(rings, [0, 2, 3, 1, 3]);
        assert_eq!(
            w.near,
            [1 << 16 | top, 0.25f32.to_bits(), 9, 0.5f32.to_bits()]
        );
        let budgets: Vec<f32> = w.budgets.iter().map(|&b| f32::from_bits(b)).collect();
        assert_eq!(budgets, [0.0, 1.5, 2.5, 0.0]);
    }

    /// A hull with more faces than a structure's 16-bit indices can name (a 9-face I_P
    /// template subdivided six times) has no structure: its contacts are clipped, and give
    /// the same overlap as the clipping alone.
    #[test]
    fn a_hull_with_more_faces_than_the_index_limit_is_clipped() {
        let params = Params {
            faces: 9,
            ..Default::default()
        };
        let mesh = generate(&params, 3, 0).unwrap().mesh;
        let topo = mesh.topology(None).unwrap();
        let started = std::time::Instant::now();
        let huge = Shape::from_mesh(&crate::geometry::subdiv::subdivide(&mesh, &topo, 6)).unwrap();
        eprintln!(
            "{} vertices, {} faces in {:?}",
            huge.vertices.len(),
            huge.face_count(),
            started.elapsed()
        );
        assert!(huge.face_count() >= INDEX_LIMIT);
        let cube = Shape::from_mesh(&cube(0.5 * huge.radius)).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for _ in 0..20 {
            let (a, b, dir, _) = thin_contact(&mut rng, &huge, &cube);
            let clipped = overlap_parts(&huge, &a, &cube, &b, &dir).map(|(o, _)| o);
            let (o, found) = overlap_kept(&huge, &a, &cube, &b, &dir, None, true).unwrap();
            assert_eq!(found, Found::None);
            assert_eq!(Some(o), clipped);
        }
    }

    /// A structure's corners, in order.
    fn corners_of(s: &Structure) -> Vec<Corner> {
        let words = s.packed().sections().corners;
        words.chunks_exact(2).map(corner_of).collect()
    }

    fn all(s: &Shape) -> Vec<u32> {
        (0..s.vertices.len() as u32).collect()
    }

    fn faces(s: &Shape) -> Vec<u32> {
        (0..s.face_count() as u32).collect()
    }

    /// Ab_3 hulls (Catmull-Clark, 3 levels) of the 6- and 9-face templates, and the 9-face I_P.
    fn large_shapes() -> Vec<Shape> {
        let mut out = Vec::new();
        for faces in [6, 9] {
            let params = Params {
                faces,
                ..Default::default()
            };
            let mesh = generate(&params, 3, 0).unwrap().mesh;
            let topo = mesh.topology(None).unwrap();
            out.push(
                Shape::from_mesh(&crate::geometry::subdiv::subdivide(&mesh, &topo, 3)).unwrap(),
            );
            if faces == 9 {
                out.push(Shape::from_mesh(&mesh).unwrap());
            }
        }
        assert!(out[0].vertices.len() >= CLIMB_MIN && out[2].vertices.len() < CLIMB_MIN);
        out
    }

    /// A thin contact of `sa` and `sb` at random orientations: B along a random direction
    /// `dir` (turned by `q`), pressed into A by 1e-4 to 1e-2 of its radius from first touch.
    fn thin_contact(
        rng: &mut impl RngCore,
        sa: &Shape,
        sb: &Shape,
    ) -> (Posed, Posed, Vec3, UnitQuaternion<f64>) {
        let a = on_odometer(sa, None, &Vec3::zeros(), &rotation(rng, 3.2));
        let (dir, q) = (direction(rng), rotation(rng, 3.2));
        let at = |d: f64| on_odometer(sb, None, &(dir * d), &q);
        let (mut lo, mut hi) = (0.0, sa.radius + sb.radius);
        for _ in 0..50 {
            let mid = 0.5 * (lo + hi);
            if overlap_parts(sa, &a, sb, &at(mid), &dir).is_some() {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        let press = sb.radius * 10f64.powf(-4.0 + 2.0 * unit_f64(rng.next_u64()));
        (a, at(hi - press), dir, q)
    }

    /// A pair back at the pose of a structure it had before (its alternate), while the kept
    /// one is from elsewhere: the alternate holds and gives the bits of a fresh overlap. When
    /// the alternate does not hold either, the structure is found afresh; without a kept one
    /// the alternate is not tried.
    #[test]
    fn an_alternate_that_holds_gives_the_fresh_overlap() {
        let shapes = large_shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(17);
        let mut held = 0;
        for t in 0..60 {
            let (sa, sb) = (&shapes[t % 3], &shapes[(t / 3) % 3]);
            let (a1, b1, d1, _) = thin_contact(&mut rng, sa, sb);
            let (a2, b2, d2, _) = thin_contact(&mut rng, sa, sb);
            // The same two bodies at the second poses, and then back at the first, their
            // odometers running on.
            let on = |s, from, to: &Posed| on_odometer(s, Some(from), &to.pos, &to.orientation);
            let (a2, b2) = (on(sa, &a1, &a2), on(sb, &b1, &b2));
            let (a1, b1) = (on(sa, &a2, &a1), on(sb, &b2, &b1));
            let (Some((o1, Found::New(s1))), Some((_, Found::New(s2)))) = (
                overlap_kept(sa, &a1, sb, &b1, &d1, None, true),
                overlap_kept(sa, &a2, sb, &b2, &d2, None, true),
            ) else {
                continue;
            };
            let at_1 = |kept: &Structure, alternate: Option<&Structure>| {
                let (o, how) = overlap_kept_or(
                    sa,
                    &a1,
                    sb,
                    &b1,
                    &d1,
                    Some(kept.packed()),
                    || alternate.map(Structure::packed),
                    true,
                )
                .unwrap();
                assert_eq!(format!("{o:?}"), format!("{o1:?}"), "pose {t}");
                how
            };
            assert_eq!(at_1(&s2, Some(&s1)), Found::Alternate, "pose {t}");
            assert_eq!(at_1(&s2, Some(&s2)), Found::New(s1.clone()), "pose {t}");
            assert_eq!(at_1(&s2, None), Found::New(s1.clone()), "pose {t}");
            let (_, how) =
                overlap_kept_or(sa, &a1, sb, &b1, &d1, None, || Some(s1.packed()), true).unwrap();
            assert_eq!(how, Found::New(s1), "pose {t}");
            held += 1;
        }
        assert!(held >= 30, "only {held} pairs of poses had structures");
    }

    #[test]
    fn large_hulls_keep_structures_checked_locally() {
        // Thin contacts of Ab_3 hulls (with each other and with an I_P body), pressed in by
        // 1e-4 to 1e-2 of the radius from first touch: the structure gives the clipped overlap,
        // and after a small motion a kept structure gives the bits of a fresh one.
        let shapes = large_shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(13);
        let (mut structured, mut held, mut changed) = (0, 0, 0);
        let trials = 90;
        for t in 0..trials {
            let (i, j) = [(0, 1), (1, 2), (2, 0)][t % 3];
            let (sa, sb) = (&shapes[i], &shapes[j]);
            let (a, b, dir, q) = thin_contact(&mut rng, sa, sb);
            let (clipped, _) = overlap_parts(sa, &a, sb, &b, &dir).unwrap();
            let Some((o, Found::New(s))) = overlap_kept(sa, &a, sb, &b, &dir, None, true) else {
                continue;
            };
            structured += 1;
            let size = 2.0 * sa.radius.max(sb.radius);
            assert!(
                (o.volume - clipped.volume).abs() <= 1e-9 * clipped.volume
                    && (o.centroid - clipped.centroid).norm() <= 1e-9 * size
                    && (o.area_b - clipped.area_b).norm() <= 1e-9 * clipped.area_b.norm(),
                "trial {t}: structure {o:?}, clipped {clipped:?}"
            );
            for step in [1e-7, 1e-4] {
                let turn = rotation(&mut rng, step);
                let at = b.pos + direction(&mut rng) * step * sb.radius;
                let moved = on_odometer(sb, Some(&b), &at, &(turn * q));
                let fresh = overlap_kept(sa, &a, sb, &moved, &dir, None, true).map(|f| f.0);
                let kept =
                    overlap_kept(sa, &a, sb, &moved, &dir, Some(s.packed()), true).map(|k| k.0);
                assert_eq!(fresh, kept, "trial {t}, step {step}");
                match Pair::new(sa, &a, sb, &moved).and_then(|p| s.evaluate(&p)) {
                    Some(_) => held += 1,
                    None => changed += 1,
                }
            }
        }
        assert!(
            structured > trials * 3 / 4,
            "{structured} of {trials} structured"
        );
        assert!(held > 40 && changed > 10, "held {held}, changed {changed}");
    }

    /// A structure renewed at new poses ([`Packed::renewed`]: its vertices' near planes and
    /// clearance found again) has the words that [`discover`] gives there, on thin contacts
    /// of Ab_3 hulls with each other and with an I_P body moved a little; and a structure
    /// whose clearance the motion has used up comes back renewed from
    /// [`Packed::evaluate_renewing`], with the fresh overlap.
    #[test]
    fn a_renewed_structure_has_the_words_found_afresh() {
        let shapes = large_shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(19);
        let (mut renewed, mut ran_out) = (0, 0);
        for t in 0..90 {
            let (i, j) = [(0, 1), (1, 2), (2, 0)][t % 3];
            let (sa, sb) = (&shapes[i], &shapes[j]);
            let (a, b, dir, q) = thin_contact(&mut rng, sa, sb);
            let Some((_, Found::New(s))) = overlap_kept(sa, &a, sb, &b, &dir, None, true) else {
                continue;
            };
            for step in [1e-7, 1e-5, 1e-4] {
                let turn = rotation(&mut rng, step);
                let at = b.pos + direction(&mut rng) * step * sb.radius;
                let moved = on_odometer(sb, Some(&b), &at, &(turn * q));
                let pair = Pair::new(sa, &a, sb, &moved).unwrap();
                let fresh = overlap_kept(sa, &a, sb, &moved, &dir, None, true);
                let Some((_, Found::New(fresh))) = fresh else {
                    continue;
                };
                let packed = s.packed();
                if packed.evaluate(&pair).is_some() {
                    // Its corners still the overlap's: renewed, it is the fresh one.
                    if let Some(r) = packed.renewed(&pair, &packed.sections()) {
                        assert_eq!(r, fresh, "trial {t}, step {step}");
                        renewed += 1;
                    }
                }
            }
            // Both bodies carried along together by a tenth of A's radius: the same overlap
            // relative to them, and its clearance used up by the motion (which counts both
            // bodies'), so evaluating renews it into the structure found there afresh.
            let shift = direction(&mut rng) * 0.1 * sa.radius;
            let (a2, b2) = (
                on_odometer(sa, Some(&a), &(a.pos + shift), &a.orientation),
                on_odometer(sb, Some(&b), &(b.pos + shift), &q),
            );
            let packed = s.packed();
            let w = packed.sections();
            if !w.clearance.is_finite() {
                continue;
            }
            let pair = Pair::new(sa, &a2, sb, &b2).unwrap();
            assert!(
                pair.moved_since(travels(w.found_at)) >= w.clearance,
                "trial {t}"
            );
            let fresh = overlap_kept(sa, &a2, sb, &b2, &dir, None, true);
            if let (Some((e, again)), Some((o, Found::New(fresh)))) =
                (packed.evaluate_renewing(&pair), fresh)
            {
                assert_eq!(format!("{e:?}"), format!("{o:?}"), "trial {t}");
                assert_eq!(again, Some(fresh), "trial {t}");
                ran_out += 1;
            }
        }
        assert!(
            renewed > 60 && ran_out > 5,
            "renewed {renewed}, ran out {ran_out}"
        );
    }

    /// The budget of an edge corner against a large hull (its crossing must stay inside a
    /// facet): B moved and turned by nine tenths of it, at random, leaves the corner a corner,
    /// on thin contacts of Ab_3 hulls with each other and with an I_P body.
    #[test]
    fn an_edge_on_a_large_hull_moved_within_its_budget_passes_its_checks() {
        let shapes = large_shapes();
        let mut rng = ChaCha8Rng::seed_from_u64(23);
        let (mut tried, mut budgets) = (0, 0);
        for t in 0..60 {
            let (i, j) = [(0, 1), (1, 2), (2, 0)][t % 3];
            let (sa, sb) = (&shapes[i], &shapes[j]);
            let (a, b, _, _) = thin_contact(&mut rng, sa, sb);
            let Some(pair) = Pair::new(sa, &a, sb, &b) else {
                continue;
            };
            let Some(s) = discover_whole(&pair) else {
                continue;
            };
            let large_edge = |c: &Corner| matches!(c, Corner::Edge { side, .. } if pair.large[1 - *side as usize]);
            for c in corners_of(&s).into_iter().filter(large_edge) {
                let budget = pair.budget(c);
                tried += 1;
                if budget <= 0.0 {
                    continue;
                }
                budgets += 1;
                for _ in 0..4 {
                    let share = unit_f64(rng.next_u64());
                    let d = direction(&mut rng);
                    moved_within_budget(&mut rng, (sa, &a), (sb, &b), c, budget, (d, share));
                }
            }
        }
        assert!(
            tried > 200 && budgets > tried / 2,
            "{budgets} of {tried} edge corners had budgets"
        );
    }

    #[test]
    fn a_corner_crossing_a_plane_refuses_the_kept_structure() {
        // A cube on its corner pressed into a big block's top face: the tip is a vertex and the
        // three edges through it cross the face. Pressed past the next vertex, the structure
        // changes: the kept one must refuse, and the overlap found again matches the clipping.
        let (c, big) = (
            Shape::from_mesh(&cube(0.5)).unwrap(),
            Shape::from_mesh(&cube(5.0)).unwrap(),
        );
        let block = big.posed(&Vec3::zeros(), &UnitQuaternion::identity(), 1.0);
        let q = UnitQuaternion::from_euler_angles(0.3, 0.5, 0.2);
        let tilted = c.posed(&Vec3::zeros(), &q, 1.0);
        let mut heights: Vec<f64> = tilted.vertices.iter().map(|v| v.z).collect();
        heights.sort_by(f64::total_cmp);
        let at = |pen: f64| c.posed(&Vec3::new(0.1, 0.2, 5.0 - heights[0] - pen), &q, 1.0);
        let first = heights[1] - heights[0];
        let shallow = at(0.5 * first);
        let (_, s) = overlap_kept(&big, &block, &c, &shallow, &Vec3::z(), None, true).unwrap();
        let Found::New(s) = s else {
            panic!("a tip in a face has a structure: {s:?}");
        };
        assert_eq!(s.corner_count(), 4);
        let near = at(0.9 * first);
        let pair = Pair::new(&big, &block, &c, &near).unwrap();
        assert!(s.evaluate(&pair).is_some(), "still one vertex in");
        let deep = at(1.1 * first);
        let pair = Pair::new(&big, &block, &c, &deep).unwrap();
        assert!(s.evaluate(&pair).is_none(), "a second vertex went in");
        let (o, again) =
            overlap_kept(&big, &block, &c, &deep, &Vec3::z(), Some(s.packed()), true).unwrap();
        let Found::New(again) = again else {
            panic!("found again: {again:?}");
        };
        assert_eq!(again.corner_count(), 6);
        let (clipped, _) = overlap_parts(&big, &block, &c, &deep, &Vec3::z()).unwrap();
        assert!(
            (o.volume - clipped.volume).abs() < 1e-12
                && (o.centroid - clipped.centroid).norm() < 1e-12
        );
    }

    #[test]
    fn faces_pressed_flat_have_no_structure() {
        // A cube stack: B's bottom face lies on A's top face plane (its corners on A's side
        // planes too). Degenerate, so left to the clipping.
        let c = Shape::from_mesh(&cube(0.5)).unwrap();
        let id = UnitQuaternion::identity();
        let (a, b) = (
            c.posed(&Vec3::zeros(), &id, 1.0),
            c.posed(&Vec3::new(0.0, 0.0, 0.999), &id, 1.0),
        );
        let (o, s) = overlap_kept(&c, &a, &c, &b, &Vec3::z(), None, true).unwrap();
        assert_eq!(s, Found::None);
        assert!((o.volume - 1e-3).abs() < 1e-12);
    }
}
