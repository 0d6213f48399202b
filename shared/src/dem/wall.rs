//! Walls: infinite planes, triangulated surfaces whose nodes can move (platens, the triaxial
//! membrane), and rigid cylinders (a container).
//!
//! A body touching a wall makes one contact with it, whatever the number of facets under it.
//! Each facet is the solid prism behind it (its triangle extruded against its normal by the
//! body's diameter); the body's overlap with each prism comes from the overlap polyhedron
//! ([`crate::dem::collision::overlap`]), and the pieces are summed: volume `V`, centroid, and the contact area
//! `S` = the sum of the facets' caps (each facet's area inside the body, along its normal).
//! Then as for bodies: normal `S / |S|`, depth `V / |S|`, point at the centroid. A flat face
//! crossing from one facet to its coplanar neighbour sees no change at all; the force is shared
//! among the facets in proportion to their volumes and passed to their nodes with the
//! barycentric weights of each piece's centroid.
//!
//! That holds for each *spot*: the pieces on facets that touch each other (share a node; on a
//! cylinder, neighbouring facets). A convex body inside a concave wall can touch it at spots
//! apart from each other, and each spot then pushes as a contact of its own ([`spots`]); the
//! contact reports their sum, with the couple that makes up their moment. Summing the spots
//! into one `V / |S|` at their joint centroid is not the gradient of any energy, and it fed
//! energy into particles wedged against a specimen's cylinder (docs/models/pack.md). Where two spots
//! join, as a facet between them starts to overlap when the body presses or slides, the force
//! jumps from the two spots' sum to the joint spot's: the particle of
//! `tests/fixtures/wedged-on-cylinder.jsonl` did so 220 times in 20 000 steps, and its audit
//! still drifts (a known failure).
//!
//! A cylinder is the prism of `segments` flat facets inscribed in the circle (the sagitta,
//! `radius (1 - cos(pi / segments))`, is the price: 0.03 % of the radius for 128 segments); only
//! the facets within reach of a body are built. Each spot's normal is the radius through its
//! centroid, so that it makes no moment about the axis.

use crate::dem::collision::broad::overlap as overlap_boxes;
use crate::dem::collision::gjk::{separating_gap, Hints, Points};
use crate::dem::collision::kept::{
    join, join_bits, pose_of, pose_words, split, split_bits, POSE_WORDS,
};
use crate::dem::collision::overlap::{
    faces_near_facet, overlap_behind_facet, overlap_behind_facet_faces, overlap_half_space_kept,
    overlap_half_space_within, overlap_parts, reach_along, Beyond, Overlap, WallFound,
};
use crate::dem::membrane::Membrane;
use crate::dem::shape::{motion_bound, Posed, Shape};
use crate::math::{basis, box_excess, Vec3};
use nalgebra::UnitQuaternion;
use std::sync::OnceLock;

/// What a wall is.
#[derive(Clone, Debug, PartialEq)]
pub enum WallKind {
    /// Solid where `normal . x <= offset`.
    Plane { normal: Vec3, offset: f64 },
    /// Triangles of `nodes`, counter-clockwise seen from the side the particles are on; solid
    /// behind each. `node_velocities` move nodes one by one (on top of the wall's velocity);
    /// `node_forces` is what the particles pushed on each node in the last step.
    Facets {
        nodes: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        node_velocities: Vec<Vec3>,
        node_forces: Vec<Vec3>,
    },
    /// Particles inside a circular tube: axis through `point` along unit `axis`, from `point`
    /// to `point + height axis`; the radius changes at `radial_rate` (m/s).
    Cylinder {
        point: Vec3,
        axis: Vec3,
        radius: f64,
        height: f64,
        segments: u32,
        radial_rate: f64,
    },
}

/// A wall: its kind, a rigid velocity, the force the particles pushed on it last step, and for
/// a facet wall whose nodes move by their own dynamics, its membrane.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    pub kind: WallKind,
    pub velocity: Vec3,
    pub force: Vec3,
    pub membrane: Option<Box<Membrane>>,
}

/// One body's contact with a wall: the combined overlap, the wall's surface velocity at the
/// contact point, for facet walls how the force is shared among the nodes (weights sum to 1),
/// and the moment of an overlap in separate spots.
pub struct WallHit {
    pub overlap: Overlap,
    pub velocity: Vec3,
    pub node_weights: Vec<(u32, f64)>,
    /// For a membrane ([`winkler`]): each node's share of the pieces' pushes, `sum_p V_p n_p
    /// w_pi` (m^3; times the contact's stiffness, N): the force the node takes, opposite.
    pub node_pushes: Vec<(u32, Vec3)>,
    /// For an overlap in separate spots (see [`spots`]): the moment of the spots' pushes about
    /// `overlap.centroid`, per unit of normal stiffness (m^2; times `kn`, N m), on top of the
    /// push at the centroid. Zero for one spot.
    pub couple: Vec3,
}

/// A piece of a body's overlap with a facet wall: the triangle, its corners, the volume,
/// centroid and cap of the overlap with its prism, and its unit normal.
type Piece = ([u32; 3], [Vec3; 3], f64, Vec3, Vec3, Vec3);

/// A body's contact with a membrane from its pieces: each facet a Winkler foundation (the
/// rubber sheet's compression, a pressure proportional to the local penetration), so each
/// piece pushes `k V_p n_p` at its centroid, `k` the membrane's stiffness (N/m^3). The pushes
/// add up across facets (a face across two coplanar facets feels one plane), each is the
/// gradient of its foundation's energy for a facet at rest, and each facet's nodes take its
/// piece's push by the barycentric weights of its centroid: the nodes feel exactly what the
/// body does. The contact reports `F = sum V_p n_p` as its depth (m^3) along its normal, at
/// the pieces' volume centroid, with the couple of the pushes about it; its surface velocity
/// is the nodes' by the pieces' volumes, with the part along `F` set so that `F . v` is the
/// power of the pushes on the nodes (what the membrane takes from the contact's work).
fn winkler(pieces: &[Piece], node_velocities: &[Vec3], rigid: &Vec3) -> Option<WallHit> {
    let volume: f64 = pieces.iter().map(|p| p.2).sum();
    if !(volume > 0.0) {
        return None;
    }
    let mut force: Vec3 = pieces.iter().map(|p| p.5 * p.2).sum();
    let point: Vec3 = pieces.iter().map(|p| p.3 * (p.2 / volume)).sum();
    // Pushes that cancel (a body pinched from opposite sides) keep a floor along the deepest.
    let floor = 1e-12 * volume;
    if !(force.norm() > floor) {
        let deepest = pieces
            .iter()
            .max_by(|a, b| a.2.total_cmp(&b.2))
            .map_or(Vec3::z(), |p| p.5);
        force = deepest * floor;
    }
    let length = force.norm();
    let normal = force / length;
    let couple = pieces
        .iter()
        .map(|p| (p.3 - point).cross(&(p.5 * p.2)))
        .sum();
    // Made to size: three nodes a piece (grown by pushes they were reallocated per contact).
    let (mut node_weights, mut node_pushes) = (
        Vec::with_capacity(3 * pieces.len()),
        Vec::with_capacity(3 * pieces.len()),
    );
    let (mut average, mut power) = (*rigid, 0.0);
    for (t, q, v, c, _, n) in pieces {
        for (k, w) in barycentric(q, c).into_iter().enumerate() {
            let node = t[k];
            let velocity = rigid + node_velocities[node as usize];
            let push = n * (v * w);
            average += node_velocities[node as usize] * (v / volume * w);
            power += push.dot(&velocity);
            node_weights.push((node, v / volume * w));
            node_pushes.push((node, push));
        }
    }
    let velocity = average + normal * (power / length - normal.dot(&average));
    let overlap = Overlap {
        volume: length,
        centroid: point,
        // depth() = volume / |area_b| = |F|, normal() along F.
        area_b: -normal,
    };
    let hit = WallHit {
        overlap,
        velocity,
        node_weights,
        node_pushes,
        couple,
    };
    Some(hit)
}

/// One spot of a wall contact: the overlap of a run of adjacent facets' pieces and the normal
/// it pushes along (`None`: the overlap's own).
struct Spot {
    overlap: Overlap,
    normal: Option<Vec3>,
}

impl Spot {
    fn normal(&self) -> Vec3 {
        self.normal.unwrap_or_else(|| self.overlap.normal())
    }
}

/// The wall's contact from its spots (at least one), as one overlap, its normal and a couple.
///
/// One spot: its overlap, pushing along its normal. Several: a convex body touches a concave
/// wall (inside a cylinder) at spots apart from each other, and each pushes as a contact of its
/// own, `kn d_g n_g` at its centroid `c_g` (`d_g = V_g / |S_g|`). Summing the spots' volumes
/// and areas into one `V / |S|` at their joint centroid instead is not the gradient of any
/// energy: a 10 mm particle wedged against the cylinder drew energy from it (docs/models/walls.md,
/// "Spots"). The result's depth is `|sum d_g n_g|`, its
/// normal that sum's direction, its point the depth-weighted mean of the centroids, and the
/// couple `sum (c_g - point) x d_g n_g` makes up the spots' moment.
fn spots(spots: &[Spot]) -> (Overlap, Vec3, Vec3) {
    if let [one] = spots {
        let mut overlap = one.overlap;
        if let Some(n) = one.normal {
            overlap.area_b = -n * overlap.area_b.norm();
        }
        return (overlap, one.normal(), Vec3::zeros());
    }
    let depth: Vec3 = spots.iter().map(|g| g.normal() * g.overlap.depth()).sum();
    let total: f64 = spots.iter().map(|g| g.overlap.depth()).sum();
    let point: Vec3 = (spots.iter())
        .map(|g| g.overlap.centroid * (g.overlap.depth() / total))
        .sum();
    let couple = (spots.iter())
        .map(|g| (g.overlap.centroid - point).cross(&(g.normal() * g.overlap.depth())))
        .sum();
    let volume: f64 = spots.iter().map(|g| g.overlap.volume).sum();
    // Spots pushing against each other (a body pinched in a fold of a membrane) may cancel:
    // their sum keeps a floor of 1e-12 of their depths, along the deepest spot's normal.
    let deepest = (spots.iter())
        .max_by(|a, b| a.overlap.depth().total_cmp(&b.overlap.depth()))
        .map_or(Vec3::z(), Spot::normal);
    let floor = 1e-12 * total;
    let depth = if depth.norm() > floor {
        depth
    } else {
        deepest * floor
    };
    let length = depth.norm();
    let normal = depth / length;
    let overlap = Overlap {
        volume,
        centroid: point,
        // depth() = volume / |area_b| = |sum d_g n_g|, normal() along that sum.
        area_b: -normal * (volume / length),
    };
    (overlap, normal, couple)
}

/// From this many vertices a body's test against a facet's prism starts with GJK
/// ([`apart_from_prism`]); below, the walk over its faces behind the plane costs less. On one
/// thread, the quick triaxial tests' loading from 5 to 6 %: Ab_3 (770 vertices a particle on
/// average) 1.72x faster with it, Ab_2 (194) 1.18x, Ab_1 (50) 0.98x; the paper-scale I_P
/// test's from 3 to 3.5 % (16) 0.84x.
const PRISM_GJK_MIN: usize = 100;

/// True when body `b` (a posed `s`), which reaches `behind` (> 0) behind the plane of triangle
/// `q` (unit normal `n`, the solid side behind), is shown apart from the prism cut as deep as
/// that by a gap of more than `margin` that GJK certifies (exact supports, see
/// [`separating_gap`]). Then the body's
/// overlap with the prism is empty. A body reaching behind the plane within each side plane
/// alone may still miss the prism: its part behind a facet that a wrapping membrane tilts lies
/// beside the facet, and finding that out by clipping costs a walk over every face behind the
/// plane.
fn apart_from_prism(
    s: &Shape,
    b: &Posed,
    q: &[Vec3; 3],
    n: &Vec3,
    behind: f64,
    margin: f64,
) -> bool {
    // Twice as deep as b reaches: the prism holds all of b's part behind the plane whatever the round-off.
    let down = -n * (2.0 * behind);
    let prism = [q[0], q[1], q[2], q[0] + down, q[1] + down, q[2] + down];
    let centre = (q[0] + q[1] + q[2]) / 3.0 + down / 2.0;
    let a = Points {
        points: &prism,
        climb: None,
        posed: None,
    };
    let mut hints: Hints = [None, None];
    separating_gap(
        a,
        Points::posed(s, b),
        &(b.pos - centre),
        margin,
        &mut hints,
    )
    .is_some()
}

/// How far a body's [`FacetSet`] reaches in front of and beside each triangle, as a fraction
/// of the body's bounding radius: the set holds while the body and the triangles' nodes have
/// moved less than that (the nodes' moves weighted by how far they tilt the planes).
const FACET_BAND_REL: f64 = 0.02;

/// Words of a facet set before its lists: the body's pose ([`pose_words`]), the band and the
/// tilt factor (2 words each), the number of the grid it was last checked with
/// ([`FacetGrid::id`], 2 words), the box the grid was asked about (lower and upper corners, 6
/// numbers of 2 words), then the counts of tracked triangles, tracked nodes and listed
/// triangles.
const FACET_SET_HEAD: usize = POSE_WORDS + 4 + 2 + 12 + 3;

/// Whether a kept [`FacetSet`] still holds ([`FacetSet::holds`]).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Hold {
    /// It does, checked with the grid it was last checked with.
    Kept,
    /// It does, checked with a newer grid: to keep with that grid's number.
    Regridded,
    /// It does not: a new set is made.
    Broken,
}

/// A body's **facet set** against a facet wall, kept from one step to the next as the walls'
/// other kept sets are (in the contact list, not in the state): the triangles near the body
/// when it was made (those the wall's [`FacetGrid`] finds for its box grown by the band,
/// ascending), their nodes where they were, and for each triangle the body may reach within
/// the band ([`faces_near_facet`]: the body's faces within the band in front of the plane or
/// behind it, and not beyond a side plane by more than the band) the list of those faces.
/// While it holds ([`FacetSet::holds`]) a body's pieces come from the listed faces alone:
/// the rejects (a climb to the plane, three to the side planes, GJK against the prism) and
/// the walks over the faces behind each plane are left out, and each listed face is clipped
/// as the walk clips it, so the pieces are the walk's, whether the set is kept or new.
/// Words: [`FACET_SET_HEAD`], the tracked triangles, each tracked node (its index and x, y,
/// z in 2 words each), each listed triangle (its index, its face count, its faces).
#[derive(Clone, Copy)]
struct FacetSet<'a>(&'a [u32]);

impl FacetSet<'_> {
    fn number(&self, k: usize) -> f64 {
        join(&self.0[POSE_WORDS + 2 * k..])
    }

    /// The number of the grid the set was last checked with.
    fn grid(&self) -> u64 {
        join_bits(&self.0[POSE_WORDS + 4..])
    }

    /// The box the grid was asked about: the body's when the set was made, grown by the band.
    fn asked(&self) -> (Vec3, Vec3) {
        let x = |k: usize| join(&self.0[POSE_WORDS + 6 + 2 * k..]);
        (Vec3::new(x(0), x(1), x(2)), Vec3::new(x(3), x(4), x(5)))
    }

    /// The same set, marked as checked with grid `id`.
    fn regridded(&self, id: u64) -> Vec<u32> {
        let mut w = self.0.to_vec();
        w[POSE_WORDS + 4..POSE_WORDS + 6].copy_from_slice(&split_bits(id));
        w
    }

    fn counts(&self) -> (usize, usize, usize) {
        let c = |k: usize| self.0[FACET_SET_HEAD - 3 + k] as usize;
        (c(0), c(1), c(2))
    }

    fn tracked(&self) -> &[u32] {
        &self.0[FACET_SET_HEAD..FACET_SET_HEAD + self.counts().0]
    }

    /// The tracked nodes: index and position when the set was made.
    fn nodes(&self) -> impl Iterator<Item = (usize, Vec3)> + '_ {
        let start = FACET_SET_HEAD + self.counts().0;
        (0..self.counts().1).map(move |j| {
            let w = &self.0[start + 7 * j..];
            let x = |k: usize| join(&w[1 + 2 * k..]);
            (w[0] as usize, Vec3::new(x(0), x(1), x(2)))
        })
    }

    /// The listed triangles, ascending, each with its faces.
    fn listed(&self) -> impl Iterator<Item = (u32, &[u32])> + '_ {
        let (tracked, nodes, listed) = self.counts();
        let mut at = FACET_SET_HEAD + tracked + 7 * nodes;
        (0..listed).map(move |_| {
            let (k, count) = (self.0[at], self.0[at + 1] as usize);
            let faces = &self.0[at + 2..at + 2 + count];
            at += 2 + count;
            (k, faces)
        })
    }

    /// True when the set still holds for body `b` (bounding radius `radius`) against `wall`,
    /// whose `grid` [`FacetGrid::fits`] the nodes as they are now: the same scale, every
    /// triangle the grid finds near the body's box tracked, and the body's motion since
    /// ([`motion_bound`]) plus the tilt factor times the farthest a tracked node has moved less
    /// than the band (by a thousandth of it, far above the round-off). Then no face outside a
    /// list, nor any triangle unlisted, can reach a triangle's prism: the listed faces hold
    /// every piece. The grid is asked about the box it was asked about when the set was made
    /// (the body's then, grown by the band: it holds the body's box while the body has moved
    /// less than the band), once for each grid: [`Hold::Regridded`] when a newer grid finds
    /// nothing untracked there, and then with the same grid nothing needs asking.
    fn holds(&self, wall: &Wall, b: &Posed, radius: f64, grid: &FacetGrid) -> Hold {
        let WallKind::Facets { nodes, .. } = &wall.kind else {
            return Hold::Broken;
        };
        if self.0.len() < FACET_SET_HEAD {
            return Hold::Broken;
        }
        let (pos, rot, scale) = pose_of(self.0);
        if scale != b.scale {
            return Hold::Broken;
        }
        let (band, tilt) = (self.number(0), self.number(1));
        let budget = 0.999 * band - motion_bound((&pos, &rot), (&b.pos, &b.orientation), radius);
        if !(budget > 0.0) {
            return Hold::Broken;
        }
        let mut farthest = 0.0f64;
        for (i, x) in self.nodes() {
            let Some(now) = nodes.get(i) else {
                return Hold::Broken;
            };
            farthest = farthest.max((now - x).norm());
        }
        if !(tilt * farthest < budget) {
            return Hold::Broken;
        }
        if self.grid() == grid.id {
            return Hold::Kept;
        }
        let (lo, hi) = self.asked();
        if grid.near_all_in(&lo, &hi, self.tracked()) {
            Hold::Regridded
        } else {
            Hold::Broken
        }
    }
}

impl Wall {
    /// A plane through `point` whose solid side is opposite `normal`.
    pub fn plane(point: Vec3, normal: Vec3) -> Wall {
        let n = normal.normalize();
        Wall::new(WallKind::Plane {
            normal: n,
            offset: n.dot(&point),
        })
    }

    /// A wall at rest.
    pub fn new(kind: WallKind) -> Wall {
        Wall {
            kind,
            velocity: Vec3::zeros(),
            force: Vec3::zeros(),
            membrane: None,
        }
    }

    /// A rigid cylinder around the particles (see [`WallKind::Cylinder`]).
    pub fn cylinder(point: Vec3, axis: Vec3, radius: f64, height: f64, segments: u32) -> Wall {
        Wall::new(WallKind::Cylinder {
            point,
            axis: axis.normalize(),
            radius,
            height,
            segments,
            radial_rate: 0.0,
        })
    }

    /// Facets of `nodes` (see [`WallKind::Facets`]).
    pub fn facets(nodes: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Wall {
        let n = nodes.len();
        Wall::new(WallKind::Facets {
            nodes,
            triangles,
            node_velocities: vec![Vec3::zeros(); n],
            node_forces: vec![Vec3::zeros(); n],
        })
    }

    /// False when nothing within the box `lo`, `hi` can touch this wall (a plane: the box is
    /// wholly outside it; facets, with their [`FacetGrid`] (made for bodies as large as this
    /// one at least): none of their prisms is near the box; [`Wall::touch`] then gives no
    /// contact for a body of that box).
    pub fn may_touch(&self, lo: &Vec3, hi: &Vec3, grid: Option<&FacetGrid>) -> bool {
        match (&self.kind, grid) {
            (WallKind::Plane { normal, offset }, _) => box_excess(&-normal, -offset, lo, hi) > 0.0,
            (WallKind::Facets { .. }, Some(g)) => g.any_near(lo, hi),
            _ => true,
        }
    }

    /// The contact of body `b` (shape `s`, bounding radius `radius`) with this wall.
    pub fn touch(&self, s: &Shape, b: &Posed, radius: f64) -> Option<WallHit> {
        self.touch_kept(s, b, radius, None, None).0
    }

    /// [`Wall::touch`], to the bit, trying the wall set `kept` the contact made last step (a
    /// plane's contact with a large hull: [`overlap_half_space_kept`]) and handing back the
    /// set to keep, touching or not (a facet set holds for a body near the wall as well as for
    /// one touching it, so a body that comes near keeps it until it touches). With `grid`, a
    /// facet wall's [`FacetGrid`] (one that fits its nodes, for bodies as large as this one at
    /// least), only the triangles near the body are tested; without it, all of them.
    pub fn touch_kept(
        &self,
        s: &Shape,
        b: &Posed,
        radius: f64,
        kept: Option<&[u32]>,
        grid: Option<&FacetGrid>,
    ) -> (Option<WallHit>, WallFound) {
        let hit = match &self.kind {
            WallKind::Plane { normal, offset } => {
                let (o, found) = overlap_half_space_kept(s, b, normal, *offset, radius, kept);
                let hit = o.map(|overlap| WallHit {
                    overlap,
                    velocity: self.velocity,
                    node_weights: Vec::new(),
                    node_pushes: Vec::new(),
                    couple: Vec3::zeros(),
                });
                return (hit, found);
            }
            WallKind::Facets {
                node_velocities, ..
            } => {
                let (pieces, found) = self.facet_pieces(s, b, radius, kept, grid);
                if self.membrane.is_some() {
                    return (winkler(&pieces, node_velocities, &self.velocity), found);
                }
                // Spots: pieces on triangles that share a node, and so on; each spot's pieces
                // summed in piece order (`labels[k]`: the label of `list[k]`'s pieces).
                let triangles: Vec<[u32; 3]> = pieces.iter().map(|p| p.0).collect();
                let label = connected(&triangles);
                let mut sums: Vec<(usize, Sum)> = Vec::new();
                for (piece, &l) in pieces.iter().zip(&label) {
                    if !sums.iter().any(|g| g.0 == l) {
                        sums.push((l, Sum::default()));
                    }
                    let k = sums.iter().position(|g| g.0 == l).expect("pushed");
                    sums[k].1.add(piece.2, &piece.3, &piece.4);
                }
                let (mut labels, mut list) = (Vec::new(), Vec::new());
                for (l, sum) in &sums {
                    if let Some(overlap) = sum.overlap() {
                        labels.push(*l);
                        list.push(Spot {
                            overlap,
                            normal: None,
                        });
                    }
                }
                if list.is_empty() {
                    return (None, found);
                }
                let (overlap, _, couple) = spots(&list);
                // Each spot's share of the force, then each piece's of its spot's by volume.
                let total: f64 = list.iter().map(|g| g.overlap.depth()).sum();
                let mut velocity = self.velocity;
                let mut node_weights = Vec::new();
                for ((t, q, v, c, _, _), l) in pieces.iter().zip(&label) {
                    let Some(k) = labels.iter().position(|k| k == l) else {
                        continue;
                    };
                    let g = &list[k];
                    let share = g.overlap.depth() / total * (v / g.overlap.volume);
                    for (k, w) in barycentric(q, c).into_iter().enumerate() {
                        let node = t[k];
                        velocity += node_velocities[node as usize] * (share * w);
                        node_weights.push((node, share * w));
                    }
                }
                let hit = WallHit {
                    overlap,
                    velocity,
                    node_weights,
                    node_pushes: Vec::new(),
                    couple,
                };
                return (Some(hit), found);
            }
            WallKind::Cylinder {
                point,
                axis,
                radius: r_cyl,
                height,
                segments,
                radial_rate,
            } => {
                // The body's box, seen along the axis: its eight corners' distances from the
                // axis and their angles about it, from the box centre's. Inside the polygon's
                // inscribed circle it touches nothing; else only the facets within its angles
                // can meet it (all of them when the box may hold the axis).
                let n_seg = *segments as usize;
                let step = std::f64::consts::TAU / n_seg as f64;
                let inscribed = r_cyl * (step / 2.0).cos();
                let (e1, e2) = basis(axis);
                let flat = |x: &Vec3| {
                    let rel = x - point;
                    (rel.dot(&e1), rel.dot(&e2))
                };
                let (cx, cy) = flat(&((b.lo + b.hi) * 0.5));
                // `far`: the largest squared distance.
                let corners = [0, 1, 2, 3, 4, 5, 6, 7].map(|k: usize| {
                    let pick =
                        |i: usize, bit: usize| if k >> bit & 1 == 0 { b.lo[i] } else { b.hi[i] };
                    flat(&Vec3::new(pick(0, 0), pick(1, 1), pick(2, 2)))
                });
                let far = (corners.iter())
                    .map(|(x, y)| x * x + y * y)
                    .fold(0.0f64, f64::max);
                if far < inscribed * inscribed {
                    return (None, WallFound::None);
                }
                let theta = cy.atan2(cx);
                // The angles about the box centre's that hold the facets to test (relative to
                // `theta`), or None for all of them.
                let window = if s.climb.is_none() {
                    reached_angles(s, b, &flat, inscribed, step)
                } else {
                    let (mut lo_angle, mut hi_angle) = (0.0f64, 0.0f64);
                    for (x, y) in corners {
                        let delta = angle_from((cx, cy), (x, y));
                        lo_angle = lo_angle.min(delta);
                        hi_angle = hi_angle.max(delta);
                    }
                    let narrow = hi_angle - lo_angle < std::f64::consts::FRAC_PI_2
                        && hi_angle < std::f64::consts::FRAC_PI_2
                        && lo_angle > -std::f64::consts::FRAC_PI_2;
                    Some(narrow.then_some((lo_angle, hi_angle)))
                };
                let (first, last) = match window {
                    None => return (None, WallFound::None),
                    Some(Some((lo_angle, hi_angle))) => (
                        ((theta + lo_angle) / step).floor() as i64,
                        ((theta + hi_angle) / step).floor() as i64,
                    ),
                    Some(None) => (0, n_seg as i64 - 1),
                };
                let count = ((last - first + 1) as usize).min(n_seg);
                // Corner j of the polygon at the tube's foot, the same bits whichever window asks
                // for it; each facet's far corner is the next one's near corner.
                let corner = |j: i64| {
                    let a = j.rem_euclid(n_seg as i64) as f64 * step;
                    point + (e1 * a.cos() + e2 * a.sin()) * *r_cyl
                };
                let up = axis * *height;
                // Runs of adjacent facets with pieces, each a spot: (first facet, last facet,
                // sum).
                let mut runs: Vec<(i64, i64, Sum)> = Vec::new();
                let mut add = |j: i64, v: f64, c: &Vec3, cap: &Vec3| match runs.last_mut() {
                    Some(run) if run.1 == j - 1 => {
                        run.1 = j;
                        run.2.add(v, c, cap);
                    }
                    _ => {
                        let mut sum = Sum::default();
                        sum.add(v, c, cap);
                        runs.push((j, j, sum));
                    }
                };
                let mut near = corner(first);
                for j in first..first + count as i64 {
                    let next = corner(j + 1);
                    // Counter-clockwise seen from the axis (the particles' side).
                    let q = [near, near + up, next + up, next];
                    near = next;
                    let n = (q[1] - q[0]).cross(&(q[2] - q[0])).normalize();
                    // Exact quick reject: all of B on the particles' side of the facet's plane.
                    if reach_along(s, b, &-n) <= -n.dot(&q[0]) {
                        continue;
                    }
                    // Most often B's part behind the plane lies within the facet: that part
                    // is the overlap, without clipping B by the facet's prism.
                    let sides = side_planes(&q, &n);
                    match overlap_half_space_within(s, b, &n, n.dot(&q[0]), &sides) {
                        Ok(Some(o)) => add(j, o.volume, &o.centroid, &-o.area_b),
                        Ok(None) => {}
                        Err(Beyond) => {
                            let depth = 2.0 * radius;
                            if let Some((v, c, cap)) =
                                facet_overlap_with(&q, &n, &sides, depth, s, b)
                            {
                                add(j, v, &c, &cap);
                            }
                        }
                    }
                }
                // All the way round: the last run and the first are one.
                if count == n_seg && runs.len() > 1 {
                    let (f0, l1) = (runs[0].0, runs[runs.len() - 1].1);
                    if f0 == first && l1 == first + n_seg as i64 - 1 {
                        let last = runs.pop().expect("two runs");
                        runs[0].2.absorb(&last.2);
                    }
                }
                // A cylinder pushes along its radius, through its axis. The facets' own
                // normals would not: at a body off a facet's middle they make a moment about
                // the axis, which nothing in a specimen between frictionless platens resists;
                // the packing then turns until the facets' moments cancel, bumping over the
                // facets as it goes (288 particles were seen turning at 0.06 rad/s).
                let list: Vec<Spot> = (runs.iter())
                    .filter_map(|(_, _, sum)| {
                        let overlap = sum.overlap()?;
                        let rel = overlap.centroid - point;
                        let radial = rel - axis * axis.dot(&rel);
                        let normal = -radial
                            .try_normalize(0.0)
                            .unwrap_or_else(|| -overlap.normal());
                        Some(Spot {
                            overlap,
                            normal: Some(normal),
                        })
                    })
                    .collect();
                if list.is_empty() {
                    return (None, WallFound::None);
                }
                let (overlap, normal, couple) = spots(&list);
                Some(WallHit {
                    velocity: self.velocity - normal * *radial_rate,
                    overlap,
                    node_weights: Vec::new(),
                    node_pushes: Vec::new(),
                    couple,
                })
            }
        };
        (hit, WallFound::None)
    }

    /// A facet wall's pieces for body `b` (a posed `s` of bounding radius `radius`): the
    /// overlap of the body with each triangle's prism, ascending by triangle, from a **facet
    /// set** kept from one step to the next ([`FacetSet`]), or made afresh when the last one
    /// (`kept`) no longer holds; with it, what to keep. Without a grid (or with a triangle
    /// folded flat near the body), every triangle is tested as [`Wall::pieces_walked`] does.
    fn facet_pieces(
        &self,
        s: &Shape,
        b: &Posed,
        radius: f64,
        kept: Option<&[u32]>,
        grid: Option<&FacetGrid>,
    ) -> (Vec<Piece>, WallFound) {
        let Some(grid) = grid else {
            return (self.pieces_walked(s, b, radius, None), WallFound::None);
        };
        let hold = kept.map_or(Hold::Broken, |w| FacetSet(w).holds(self, b, radius, grid));
        let fresh = match (hold, kept) {
            (Hold::Kept, _) => None,
            (Hold::Regridded, Some(w)) => Some(FacetSet(w).regridded(grid.id)),
            _ => match self.facet_set(s, b, radius, grid) {
                Some(w) => Some(w),
                None => {
                    return (
                        self.pieces_walked(s, b, radius, Some(grid)),
                        WallFound::None,
                    )
                }
            },
        };
        let words = fresh.as_deref().or(kept).expect("kept or made");
        let pieces = self.set_pieces(s, b, radius, FacetSet(words));
        (pieces, fresh.map_or(WallFound::Kept, WallFound::New))
    }

    /// A new facet set of body `b` ([`FacetSet`]), or `None` when a triangle near it is folded
    /// flat (it has no plane to test against).
    fn facet_set(&self, s: &Shape, b: &Posed, radius: f64, grid: &FacetGrid) -> Option<Vec<u32>> {
        let WallKind::Facets {
            nodes, triangles, ..
        } = &self.kind
        else {
            return None;
        };
        let band = FACET_BAND_REL * radius;
        let depth = self.prism_depth(radius);
        let pad = Vec3::repeat(band);
        let (blo, bhi) = (b.lo - pad, b.hi + pad);
        let misses = |lo: &Vec3, hi: &Vec3| (0..3).any(|k| lo[k] > bhi[k] || blo[k] > hi[k]);
        let reach = Vec3::repeat(depth + band);
        let tracked = grid.near(&blo, &bhi);
        let mut listed: Vec<(u32, Vec<u32>)> = Vec::new();
        let mut altitude = f64::INFINITY;
        for &k in &tracked {
            let t = &triangles[k as usize];
            let q = t.map(|i| nodes[i as usize]);
            let n = (q[1] - q[0]).cross(&(q[2] - q[0]));
            let scale = (q[1] - q[0])
                .norm_squared()
                .max((q[2] - q[0]).norm_squared());
            if !(n.norm() > 1e-12 * scale) {
                return None;
            }
            altitude = altitude.min(smallest_altitude(&q, &n));
            let lo = q[0].inf(&q[1]).inf(&q[2]);
            let hi = q[0].sup(&q[1]).sup(&q[2]);
            if misses(&(lo - reach), &(hi + reach)) {
                continue;
            }
            let n = n.normalize();
            let back = -n * (depth + band);
            if misses(&(lo.inf(&(lo + back)) - pad), &(hi.sup(&(hi + back)) + pad)) {
                continue;
            }
            let d = n.dot(&q[0]);
            let behind = reach_along(s, b, &-n) + d;
            if behind + band <= 0.0 {
                continue;
            }
            let sides = side_planes(&q, &n);
            let beyond = |(m, e): &(Vec3, f64)| match s.climb {
                None => (0..s.vertices.len()).all(|i| m.dot(&b.vertex(s, i)) > e + band),
                Some(_) => {
                    box_excess(&-m, -(e + band), &b.lo, &b.hi) < 0.0
                        || -reach_along(s, b, &-m) > e + band
                }
            };
            if sides.iter().any(beyond) {
                continue;
            }
            if s.vertices.len() >= PRISM_GJK_MIN
                && apart_from_prism(s, b, &q, &n, behind + band, band)
            {
                continue;
            }
            if let Some(faces) = faces_near_facet(s, b, &n, d, &sides, band) {
                if !faces.is_empty() {
                    listed.push((k, faces));
                }
            }
        }
        let mut node_ids: Vec<u32> = (tracked.iter())
            .flat_map(|&k| triangles[k as usize])
            .collect();
        node_ids.sort_unstable();
        node_ids.dedup();
        // How much a facet's plane and side planes move, at the points of the body that
        // matter (within its width and the prism's depth of the triangle), for each unit its
        // nodes move: tilting by up to twice the move over the triangle's altitude.
        let tilt = 1.0 + 2.0 * (2.0 * radius + depth) / altitude;
        let mut w: Vec<u32> = pose_words(&b.pos, &b.orientation, b.scale).collect();
        w.extend([band, tilt].into_iter().flat_map(split));
        w.extend(split_bits(grid.id));
        w.extend(blo.iter().chain(bhi.iter()).flat_map(|&x| split(x)));
        w.extend([
            tracked.len() as u32,
            node_ids.len() as u32,
            listed.len() as u32,
        ]);
        w.extend_from_slice(&tracked);
        for &i in &node_ids {
            let x = nodes[i as usize];
            w.push(i);
            w.extend([x.x, x.y, x.z].into_iter().flat_map(split));
        }
        for (k, faces) in &listed {
            w.extend([*k, faces.len() as u32]);
            w.extend_from_slice(faces);
        }
        Some(w)
    }

    /// The pieces of body `b` from the facet set `set`, which holds: each listed triangle's
    /// overlap from its listed faces, ascending by triangle.
    fn set_pieces(&self, s: &Shape, b: &Posed, radius: f64, set: FacetSet) -> Vec<Piece> {
        let WallKind::Facets {
            nodes, triangles, ..
        } = &self.kind
        else {
            return Vec::new();
        };
        // At most one piece a listed triangle: made to that size, not grown.
        let mut pieces = Vec::with_capacity(set.counts().2);
        let misses = |lo: &Vec3, hi: &Vec3| (0..3).any(|k| lo[k] > b.hi[k] || b.lo[k] > hi[k]);
        let depth = self.prism_depth(radius);
        let reach = Vec3::repeat(depth);
        for (k, faces) in set.listed() {
            let t = &triangles[k as usize];
            let q = t.map(|i| nodes[i as usize]);
            // The walk's box rejects, as it makes them (the prism is `depth` deep), and no
            // plane when folded flat; its exact rejects need no test: the faces show them.
            let lo = q[0].inf(&q[1]).inf(&q[2]);
            let hi = q[0].sup(&q[1]).sup(&q[2]);
            if misses(&(lo - reach), &(hi + reach)) {
                continue;
            }
            let n = (q[1] - q[0]).cross(&(q[2] - q[0]));
            let scale = (q[1] - q[0])
                .norm_squared()
                .max((q[2] - q[0]).norm_squared());
            if !(n.norm() > 1e-12 * scale) {
                continue;
            }
            let n = n.normalize();
            let back = -n * depth;
            if misses(&lo.inf(&(lo + back)), &hi.sup(&(hi + back))) {
                continue;
            }
            let sides = side_planes(&q, &n);
            if let Some((v, c, cap)) =
                overlap_behind_facet_faces(s, b, &n, n.dot(&q[0]), &sides, faces)
            {
                pieces.push((*t, q, v, c, cap, n));
            }
        }
        pieces
    }

    /// Every piece of body `b` by testing each triangle near it (all of them without a grid):
    /// quick rejects, then the walk over the body's faces behind the triangle's plane.
    fn pieces_walked(
        &self,
        s: &Shape,
        b: &Posed,
        radius: f64,
        grid: Option<&FacetGrid>,
    ) -> Vec<Piece> {
        let WallKind::Facets {
            nodes, triangles, ..
        } = &self.kind
        else {
            return Vec::new();
        };
        let mut pieces = Vec::new();
        let misses = |lo: &Vec3, hi: &Vec3| (0..3).any(|k| lo[k] > b.hi[k] || b.lo[k] > hi[k]);
        // How deep behind a facet the body is looked for: its width, or for a membrane
        // (whose contacts are shallow) at most the sheet's reach.
        let depth = self.prism_depth(radius);
        let reach = Vec3::repeat(depth);
        // The triangles whose prisms' boxes may meet the body's (all of them without a
        // grid), ascending: a superset of those that pass the quick rejects below, so
        // the same pieces in the same order.
        let near = match grid {
            Some(g) => g.near(&b.lo, &b.hi),
            None => (0..triangles.len() as u32).collect(),
        };
        for t in near.iter().map(|&k| &triangles[k as usize]) {
            let q = t.map(|i| nodes[i as usize]);
            // Quick reject: the prism's box misses the body's box (first the triangle's
            // box grown by the prism's depth every way, then the prism's own).
            let lo = q[0].inf(&q[1]).inf(&q[2]);
            let hi = q[0].sup(&q[1]).sup(&q[2]);
            if misses(&(lo - reach), &(hi + reach)) {
                continue;
            }
            // A triangle of a deformed membrane folded flat has no plane: skipped.
            let n = (q[1] - q[0]).cross(&(q[2] - q[0]));
            let scale = (q[1] - q[0])
                .norm_squared()
                .max((q[2] - q[0]).norm_squared());
            if !(n.norm() > 1e-12 * scale) {
                continue;
            }
            let n = n.normalize();
            let back = -n * depth;
            if misses(&lo.inf(&(lo + back)), &hi.sup(&(hi + back))) {
                continue;
            }
            // Exact quick reject, first as the cheapest: all of B on the particles'
            // side of the facet's plane (one climb, where the side planes take three).
            let behind = reach_along(s, b, &-n) + n.dot(&q[0]);
            if behind <= 0.0 {
                continue;
            }
            // B's overlap with the triangle's prism, from B's faces behind its plane
            // (the prism is as deep as B is wide: a body that meets the plane reaches
            // no deeper).
            let sides = side_planes(&q, &n);
            // Quick reject: the body wholly beyond one of the prism's side planes (its
            // vertices, or for a large hull its box and then its lowest vertex, found
            // by a climb), so that every face's clipping would come out empty.
            let beyond = |(m, e): &(Vec3, f64)| match s.climb {
                None => (0..s.vertices.len()).all(|i| m.dot(&b.vertex(s, i)) > *e),
                Some(_) => box_excess(&-m, -e, &b.lo, &b.hi) < 0.0 || -reach_along(s, b, &-m) > *e,
            };
            if sides.iter().any(beyond) {
                continue;
            }
            if s.vertices.len() >= PRISM_GJK_MIN && apart_from_prism(s, b, &q, &n, behind, 0.0) {
                continue;
            }
            if let Some((v, c, cap)) = overlap_behind_facet(s, b, &n, n.dot(&q[0]), &sides) {
                pieces.push((*t, q, v, c, cap, n));
            }
        }
        pieces
    }

    /// How deep behind its facets a body of bounding radius `radius` is looked for: its width,
    /// or for a membrane at most the sheet's reach ([`crate::dem::membrane::Sheet::reach`]).
    pub fn prism_depth(&self, radius: f64) -> f64 {
        match &self.membrane {
            Some(m) => (2.0 * radius).min(m.sheet.reach),
            None => 2.0 * radius,
        }
    }

    /// Moves the wall by its velocities over `dt`.
    pub fn advance(&mut self, dt: f64) {
        let v = self.velocity;
        match &mut self.kind {
            WallKind::Plane { normal, offset } => *offset += normal.dot(&v) * dt,
            WallKind::Facets {
                nodes,
                node_velocities,
                ..
            } => {
                for (p, nv) in nodes.iter_mut().zip(node_velocities.iter()) {
                    *p += (v + nv) * dt;
                }
            }
            WallKind::Cylinder {
                point,
                radius,
                radial_rate,
                ..
            } => {
                *point += v * dt;
                *radius += *radial_rate * dt;
            }
        }
    }

    /// Clears the forces of the last step.
    pub fn clear_forces(&mut self) {
        self.force = Vec3::zeros();
        if let WallKind::Facets { node_forces, .. } = &mut self.kind {
            node_forces.iter_mut().for_each(|f| *f = Vec3::zeros());
        }
    }

    /// Adds `f`, pushed by a particle through a contact with these node weights.
    pub fn push(&mut self, f: &Vec3, node_weights: &[(u32, f64)]) {
        self.force += f;
        if let WallKind::Facets { node_forces, .. } = &mut self.kind {
            for &(node, w) in node_weights {
                node_forces[node as usize] += f * w;
            }
        }
    }

    /// Adds `f`, pushed by a particle through a membrane contact of stiffness `k` with these
    /// node pushes ([`winkler`]): each node takes minus `k` times its push, and what `f` holds
    /// besides (a shear force) goes by the weights.
    pub fn push_membrane(
        &mut self,
        f: &Vec3,
        k: f64,
        node_weights: &[(u32, f64)],
        node_pushes: &[(u32, Vec3)],
    ) {
        self.force += f;
        let normal: Vec3 = node_pushes.iter().map(|(_, p)| p).sum::<Vec3>() * k;
        let rest = f + normal;
        if let WallKind::Facets { node_forces, .. } = &mut self.kind {
            for &(node, p) in node_pushes {
                node_forces[node as usize] -= p * k;
            }
            for &(node, w) in node_weights {
                node_forces[node as usize] += rest * w;
            }
        }
    }
}

/// The triangles of a grid of `cols` x `rows` squares whose `(cols + 1) x (rows + 1)` nodes
/// are numbered row by row: two to a square, counter-clockwise when the rows run
/// counter-clockwise from the columns.
pub fn grid_triangles(cols: usize, rows: usize) -> Vec<[u32; 3]> {
    let id = |i: usize, j: usize| (j * (cols + 1) + i) as u32;
    (0..rows)
        .flat_map(|j| (0..cols).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            [
                [id(i, j), id(i + 1, j), id(i + 1, j + 1)],
                [id(i, j), id(i + 1, j + 1), id(i, j + 1)],
            ]
        })
        .collect()
}

/// The triangles of a facet wall by cell of a uniform grid over their prisms' boxes (for the
/// deepest prism of the scene's bodies), so that a body tests only the triangles near it (a
/// box's sides as 4 x 1 152 facets, tested by every body that reached the wall, made the 2000
/// I_P bed's steps 20x dearer: `benches/walls.rs`). Each box is grown by a skin, so that the
/// grid stays good while the nodes move less than it allows ([`FacetGrid::fits`]): made anew
/// every step, it took 6 % of a triaxial test's step on one thread, and a whole step's share
/// of the other thread's time on two, as one thread made it.
#[derive(Clone, Debug)]
pub struct FacetGrid {
    /// Each triangle's prism's box grown by the skin (see [`FacetGrid::of`]).
    boxes: Vec<(Vec3, Vec3)>,
    /// All triangles' box.
    bounds: (Vec3, Vec3),
    cells: Cells,
    /// Cell `c`'s triangles are `ids[start[c]..start[c + 1]]`, ascending.
    start: Vec<u32>,
    ids: Vec<u32>,
    /// What the grid was made for: the wall's triangles and nodes then, the bodies' largest
    /// bounding radius and the prisms' depth for it, the skin, and the smallest altitude of a
    /// triangle then.
    triangles: Vec<[u32; 3]>,
    nodes: Vec<Vec3>,
    radius: f64,
    depth: f64,
    skin: f64,
    altitude: f64,
    /// This grid's number, unlike any other grid's made in this process: a facet set made
    /// with this grid need not check the grid again ([`FacetSet::holds`]).
    id: u64,
}

/// The smallest altitude of triangle `q` (the one to its longest side), from its corners'
/// cross product `cross`.
fn smallest_altitude(q: &[Vec3; 3], cross: &Vec3) -> f64 {
    let longest = [(q[1] - q[0]), (q[2] - q[1]), (q[0] - q[2])]
        .iter()
        .map(|e| e.norm_squared())
        .fold(0.0, f64::max);
    cross.norm() / longest.sqrt()
}

/// The box of triangle `q`'s prism `depth` deep, grown a little for round-off (bodies of
/// bounding radius `radius` at most).
fn prism_box(q: &[Vec3; 3], depth: f64, radius: f64) -> (Vec3, Vec3) {
    let (lo, hi) = (q[0].inf(&q[1]).inf(&q[2]), q[0].sup(&q[1]).sup(&q[2]));
    let back = -(q[1] - q[0]).cross(&(q[2] - q[0])).normalize() * depth;
    let (lo, hi) = (lo.inf(&(lo + back)), hi.sup(&(hi + back)));
    let size = lo.abs().sup(&hi.abs()).max();
    let pad = Vec3::repeat(1e-9 * radius + 1e-12 * size);
    (lo - pad, hi + pad)
}

/// The skin a [`FacetGrid`]'s boxes are grown by, as a fraction of their mean side. On the
/// paper-scale triaxial test (10 mm facets, prisms 10 mm deep) it is about 1 mm, and the grid
/// is made anew every few hundred steps while the platens move.
const GRID_SKIN_REL: f64 = 0.05;

/// The number of the next [`FacetGrid`] made.
static NEXT_GRID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(1);

impl FacetGrid {
    /// The grid of a facet wall's triangles for bodies of bounding radius `radius` at most;
    /// `None` for other walls, or a wall of no triangles. Each triangle is listed by the box of
    /// its prism for a body of that radius (extruded by `2 radius` against its normal, as
    /// [`Wall::touch`] takes it), grown by the skin ([`GRID_SKIN_REL`] of the boxes' mean
    /// side) and a little for round-off: a body's prism of a triangle lies within it while
    /// the grid [`FacetGrid::fits`] the wall.
    pub fn of(wall: &Wall, radius: f64) -> Option<FacetGrid> {
        let WallKind::Facets {
            nodes, triangles, ..
        } = &wall.kind
        else {
            return None;
        };
        let depth = wall.prism_depth(radius);
        let mut altitude = f64::INFINITY;
        let mut boxes: Vec<(Vec3, Vec3)> = (triangles.iter())
            .map(|t| {
                let q = t.map(|i| nodes[i as usize]);
                let cross = (q[1] - q[0]).cross(&(q[2] - q[0]));
                altitude = altitude.min(smallest_altitude(&q, &cross));
                prism_box(&q, depth, radius)
            })
            .collect();
        let n = boxes.len();
        let side = boxes.iter().map(|b| (b.1 - b.0).max()).sum::<f64>() / n as f64;
        // No skin where a triangle is folded flat (no altitude): made anew at every move.
        let skin = if altitude > 0.0 {
            GRID_SKIN_REL * side
        } else {
            0.0
        };
        for b in &mut boxes {
            *b = (b.0 - Vec3::repeat(skin), b.1 + Vec3::repeat(skin));
        }
        let lo = boxes.iter().map(|b| b.0).reduce(|a, b| a.inf(&b))?;
        let hi = boxes.iter().map(|b| b.1).reduce(|a, b| a.sup(&b))?;
        // Cells about a triangle's size, and at most a few per triangle.
        let extent = hi - lo;
        let count = |cell: f64| extent.map(|e| ((e / cell).floor() as usize + 1).min(1 << 20));
        let mut cell = side.max(extent.max() * 1e-6).max(f64::MIN_POSITIVE);
        let most = 4 * n + 64;
        let cells = |c: f64| count(c).iter().product::<usize>();
        while cells(cell) > most {
            cell *= 1.5;
        }
        let d = count(cell);
        let dims = [d.x, d.y, d.z];
        let cells = Cells { lo, cell, dims };
        // Counted, then placed: each cell's triangles in ascending order.
        let mut start = vec![0u32; dims.iter().product::<usize>() + 1];
        for b in &boxes {
            cells.each(&b.0, &b.1, |c| start[c + 1] += 1);
        }
        for c in 1..start.len() {
            start[c] += start[c - 1];
        }
        let mut at = start.clone();
        let mut ids = vec![0; *start.last().expect("a cell") as usize];
        for (k, b) in boxes.iter().enumerate() {
            cells.each(&b.0, &b.1, |c| {
                ids[at[c] as usize] = k as u32;
                at[c] += 1;
            });
        }
        Some(FacetGrid {
            boxes,
            bounds: (lo, hi),
            cells,
            start,
            ids,
            triangles: triangles.clone(),
            nodes: nodes.clone(),
            radius,
            depth,
            skin,
            altitude,
            id: NEXT_GRID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        })
    }

    /// `grid` kept while it [`FacetGrid::fits`] `wall` for bodies of bounding radius `radius`,
    /// else made anew.
    pub fn refresh(grid: &mut Option<FacetGrid>, wall: &Wall, radius: f64) {
        if !(grid.as_ref()).is_some_and(|g| g.fits(wall, radius)) {
            *grid = FacetGrid::of(wall, radius);
        }
    }

    /// Whether the grid still serves `wall` for bodies of bounding radius `radius`: made for
    /// the same triangles, radius and depth, and each prism's box now within its box in the
    /// grid. A node that moved by `delta` moves a box's corners by `delta` and tilts the
    /// triangle's plane by at most `4 delta / (h - 2 delta)` (`h` the smallest altitude when
    /// the grid was made: the linear height change over a triangle whose corners rise by at
    /// most `2 delta` relative to each other has a slope of at most `4 delta / h`), which
    /// moves the prism's far corners by `depth` times that: while the farthest node has moved
    /// less than takes that sum to the skin (less a thousandth), the grid serves.
    pub fn fits(&self, wall: &Wall, radius: f64) -> bool {
        let WallKind::Facets {
            nodes, triangles, ..
        } = &wall.kind
        else {
            return false;
        };
        if radius != self.radius
            || wall.prism_depth(radius) != self.depth
            || nodes.len() != self.nodes.len()
            || *triangles != self.triangles
        {
            return false;
        }
        let delta = (nodes.iter().zip(&self.nodes))
            .map(|(x, x0)| (x - x0).norm_squared())
            .fold(0.0, f64::max)
            .sqrt();
        let h = self.altitude - 2.0 * delta;
        h > 0.0 && delta + self.depth * 4.0 * delta / h < 0.999 * self.skin
    }

    /// The triangles listed in cell `c`.
    fn listed(&self, c: usize) -> &[u32] {
        &self.ids[self.start[c] as usize..self.start[c + 1] as usize]
    }

    /// The triangles whose prisms' boxes may overlap the box `lo`, `hi` (of a body no larger
    /// than the grid was made for), ascending.
    pub fn near(&self, lo: &Vec3, hi: &Vec3) -> Vec<u32> {
        let mut out = Vec::new();
        let b = (*lo, *hi);
        if !overlap_boxes(&b, &self.bounds) {
            return out;
        }
        self.cells.each(lo, hi, |c| {
            let meets = |&&k: &&u32| overlap_boxes(&self.boxes[k as usize], &b);
            out.extend(self.listed(c).iter().filter(meets));
        });
        out.sort_unstable();
        out.dedup();
        out
    }

    /// Whether every triangle [`FacetGrid::near`] would find is in `tracked` (ascending): the
    /// same test, without making the list.
    pub fn near_all_in(&self, lo: &Vec3, hi: &Vec3, tracked: &[u32]) -> bool {
        let b = (*lo, *hi);
        if !overlap_boxes(&b, &self.bounds) {
            return true;
        }
        let mut all = true;
        self.cells.each(lo, hi, |c| {
            if all {
                all = (self.listed(c).iter())
                    .filter(|&&k| overlap_boxes(&self.boxes[k as usize], &b))
                    .all(|k| tracked.binary_search(k).is_ok());
            }
        });
        all
    }

    /// Whether [`FacetGrid::near`] would find any triangle.
    pub fn any_near(&self, lo: &Vec3, hi: &Vec3) -> bool {
        let b = (*lo, *hi);
        if !overlap_boxes(&b, &self.bounds) {
            return false;
        }
        let mut any = false;
        self.cells.each(lo, hi, |c| {
            let meets = |&k: &u32| overlap_boxes(&self.boxes[k as usize], &b);
            any = any || self.listed(c).iter().any(meets);
        });
        any
    }
}

/// A uniform grid of cubes of side `cell`, `dims` of them along x, y, z from `lo`.
#[derive(Clone, Copy, Debug)]
struct Cells {
    lo: Vec3,
    cell: f64,
    dims: [usize; 3],
}

impl Cells {
    /// Calls `f` with each cell the box `lo`, `hi` overlaps (clamped to the grid).
    fn each(&self, lo: &Vec3, hi: &Vec3, mut f: impl FnMut(usize)) {
        let at = |x: f64, k: usize| {
            let c = ((x - self.lo[k]) / self.cell).floor();
            (c.max(0.0) as usize).min(self.dims[k] - 1)
        };
        let (a, b) = (
            [0, 1, 2].map(|k| at(lo[k], k)),
            [0, 1, 2].map(|k| at(hi[k], k)),
        );
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    f((z * self.dims[1] + y) * self.dims[0] + x);
                }
            }
        }
    }
}

/// Sums facet pieces into one overlap.
#[derive(Default)]
struct Sum {
    volume: f64,
    moment: Vec3,
    cap: Vec3,
}

impl Sum {
    fn add(&mut self, v: f64, c: &Vec3, cap: &Vec3) {
        self.volume += v;
        self.moment += c * v;
        self.cap += cap;
    }

    /// Adds another sum's pieces.
    fn absorb(&mut self, other: &Sum) {
        self.volume += other.volume;
        self.moment += other.moment;
        self.cap += other.cap;
    }

    fn overlap(&self) -> Option<Overlap> {
        // A body wholly behind the facets has no cap: it has left the container, and no
        // direction to push it back is right.
        if self.volume <= 0.0 || self.cap.norm() == 0.0 {
            return None;
        }
        Some(Overlap {
            volume: self.volume,
            centroid: self.moment / self.volume,
            area_b: -self.cap,
        })
    }
}

/// The angle of `(x, y)` from `(cx, cy)`, counter-clockwise about the origin, in (-pi, pi].
fn angle_from((cx, cy): (f64, f64), (x, y): (f64, f64)) -> f64 {
    (cx * y - cy * x).atan2(cx * x + cy * y)
}

/// The angles (about the axis, relative to `theta`, the angle of the body's box centre) of the
/// facets of a cylinder that a small body may reach: `Some(Some((lo, hi)))`, `Some(None)` for
/// all facets, `None` for none. `flat` gives a point's coordinates across the axis, `inscribed`
/// is the facets' distance from the axis and `step` their angle. A facet's plane touches the
/// inscribed circle at the facet's middle, so a vertex at distance `rho > inscribed` and angle
/// `phi` is beyond the plane of the facet whose middle is at `psi` only when
/// `|phi - psi| < acos(inscribed / rho)`, and no vertex inside the inscribed circle is beyond
/// any; a convex body reaches past a plane only with a vertex. The window is that of the
/// vertices outside, widened by a facet each way (whose exact test, `reach_along`, then
/// decides): it replaces the box's, whose corners' angles took in 3-10 facets of a 128-facet
/// tube that each cost a scan of the body's vertices.
fn reached_angles(
    s: &Shape,
    b: &Posed,
    flat: &impl Fn(&Vec3) -> (f64, f64),
    inscribed: f64,
    step: f64,
) -> Option<Option<(f64, f64)>> {
    let (cx, cy) = flat(&((b.lo + b.hi) * 0.5));
    let limit = inscribed * (1.0 - 1e-9);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..b.vertex_count(s) {
        let (x, y) = flat(&b.vertex(s, i));
        let rho = x.hypot(y);
        if rho <= limit {
            continue;
        }
        // The vertex's angle from the box centre's, and the half-width of the facet middles
        // whose planes it may be beyond.
        let delta = angle_from((cx, cy), (x, y));
        let half = (limit / rho).acos();
        lo = lo.min(delta - half);
        hi = hi.max(delta + half);
    }
    if lo > hi {
        return None;
    }
    // Facet middles in [lo, hi]: the facets that hold those angles, and one more each way.
    let (lo, hi) = (lo - step, hi + step);
    let narrow = hi - lo < std::f64::consts::PI;
    Some(narrow.then_some((lo, hi)))
}

/// For triangles given by their node indices: each one's component label (the smallest index of
/// the triangles joined to it through shared nodes).
fn connected(triangles: &[[u32; 3]]) -> Vec<usize> {
    let mut label: Vec<usize> = (0..triangles.len()).collect();
    loop {
        let mut changed = false;
        for i in 0..triangles.len() {
            for j in i + 1..triangles.len() {
                let touch = triangles[i].iter().any(|n| triangles[j].contains(n));
                if touch && label[i] != label[j] {
                    let l = label[i].min(label[j]);
                    (label[i], label[j]) = (l, l);
                    changed = true;
                }
            }
        }
        if !changed {
            return label;
        }
    }
}

/// Barycentric weights of `p` (projected onto the triangle's plane), clamped and renormalised.
fn barycentric(q: &[Vec3; 3], p: &Vec3) -> [f64; 3] {
    let (e0, e1, ep) = (q[1] - q[0], q[2] - q[0], p - q[0]);
    let (d00, d01, d11) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
    let (d20, d21) = (ep.dot(&e0), ep.dot(&e1));
    let den = d00 * d11 - d01 * d01;
    let v = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0);
    let u = (1.0 - v - w).max(0.0);
    let s = u + v + w;
    [u / s, v / s, w / s]
}

/// Topology of the prism under a facet of `k` corners (k = 3 or 4): top face first (the cap),
/// then the bottom and the sides. Only the face lists (and the faces around each vertex) are used.
fn prism(k: usize) -> &'static Shape {
    static PRISMS: OnceLock<[Shape; 2]> = OnceLock::new();
    let make = |k: usize| {
        let mut faces: Vec<Vec<u32>> = vec![(0..k as u32).collect()];
        faces.push((0..k as u32).rev().map(|i| i + k as u32).collect());
        for i in 0..k as u32 {
            let j = (i + 1) % k as u32;
            faces.push(vec![i, i + k as u32, j + k as u32, j]);
        }
        let mut face_start = vec![0u32];
        let mut face_verts = Vec::new();
        for f in &faces {
            face_verts.extend(f);
            face_start.push(face_verts.len() as u32);
        }
        let (vertex_face_start, vertex_faces) =
            crate::dem::shape::incidence(&face_start, &face_verts);
        Shape {
            name: format!("prism{k}"),
            vertices: Vec::new(),
            face_start,
            face_verts,
            vertex_face_start,
            vertex_faces,
            normals: Vec::new(),
            offsets: Vec::new(),
            volume: 0.0,
            moments: Vec3::zeros(),
            radius: 0.0,
            centroid_in_mesh: Vec3::zeros(),
            frame_in_mesh: UnitQuaternion::identity(),
            climb: None,
        }
    };
    &PRISMS.get_or_init(|| [make(3), make(4)])[k - 3]
}

/// The side planes `m . x <= e` of the prism behind the convex facet `q` (normal `n`), one per
/// edge, outward.
fn side_planes<const K: usize>(q: &[Vec3; K], n: &Vec3) -> [(Vec3, f64); K] {
    std::array::from_fn(|i| {
        let m = (q[(i + 1) % K] - q[i]).cross(n).normalize();
        (m, m.dot(&q[i]))
    })
}

/// The overlap of body B with the prism behind the convex facet `q` (counter-clockwise about
/// its unit normal `n`, side planes `sides` from [`side_planes`]), `depth` deep: volume,
/// centroid and the cap (the facet's area inside B, along `n`).
fn facet_overlap_with<const K: usize>(
    q: &[Vec3; K],
    n: &Vec3,
    sides: &[(Vec3, f64); K],
    depth: f64,
    sb: &Shape,
    b: &Posed,
) -> Option<(f64, Vec3, Vec3)> {
    let mut vertices: Vec<Vec3> = q.to_vec();
    vertices.extend(q.iter().map(|p| p - n * depth));
    let mut normals = vec![*n, -n];
    let mut offsets = vec![n.dot(&q[0]), -n.dot(&vertices[K])];
    for (m, e) in sides {
        normals.push(*m);
        offsets.push(*e);
    }
    let (lo, hi) = crate::math::bounding_box(&vertices)?;
    let posed = Posed {
        vertices,
        normals,
        offsets,
        lo,
        hi,
        ..Default::default() // planes given: no pose needed
    };
    let (o, cap) = overlap_parts(prism(K), &posed, sb, b, n)?;
    Some((o.volume, o.centroid, cap))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::cube;
    use approx::assert_relative_eq;

    fn cube_at(p: Vec3) -> (Shape, Posed) {
        let s = Shape::from_mesh(&cube(0.5)).unwrap();
        let b = s.posed(&p, &UnitQuaternion::identity(), 1.0);
        (s, b)
    }

    /// The step skips the pairs `may_touch` rules out: for a plane, none of them touches.
    #[test]
    fn a_plane_rules_out_only_boxes_that_cannot_touch_it() {
        let wall = Wall::plane(
            Vec3::new(0.0, 0.0, 0.1),
            Vec3::new(0.3, -0.2, 1.0).normalize(),
        );
        let (mut out, mut touching) = (0, 0);
        for k in 0..400 {
            let t = k as f64 / 400.0;
            let at = Vec3::new(0.7 * (9.0 * t).sin(), 0.4 * (5.0 * t).cos(), -0.8 + 3.0 * t);
            let s = Shape::from_mesh(&cube(0.5)).unwrap();
            let turn = UnitQuaternion::from_euler_angles(7.0 * t, 3.0 * t, -2.0 * t);
            let b = s.posed(&at, &turn, 1.0);
            let hit = wall.touch(&s, &b, s.radius).is_some();
            if !wall.may_touch(&b.lo, &b.hi, None) {
                assert!(!hit, "pose {k}: ruled out, yet touching");
                out += 1;
            }
            touching += usize::from(hit);
        }
        assert!(
            out > 50 && touching > 50,
            "{out} ruled out, {touching} touching"
        );
    }

    /// The facet overlap from B's faces behind the plane alone ([`overlap_behind_facet`]) is
    /// the clipping of B by the facet's prism: random triangles (some slivers) against a cube,
    /// a polyhedron and a large hull (climbed) of sizes from a tenth to ten times theirs, at
    /// random poses across and near their planes, grazing and deep; and where GJK shows B apart
    /// from the prism ([`apart_from_prism`]), the clipping finds nothing.
    #[test]
    fn a_facet_overlap_from_the_faces_behind_equals_the_prism_clipping() {
        use rand::{RngCore, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(8);
        let mut u = move || crate::math::unit_f64(rng.next_u64());
        let polyhedron =
            crate::geometry::polygen::generate(&crate::geometry::polygen::Params::default(), 3, 0)
                .unwrap()
                .mesh;
        let topo = polyhedron.topology(None).unwrap();
        let hull = crate::geometry::subdiv::subdivide(&polyhedron, &topo, 3);
        let shapes = [
            Shape::from_mesh(&cube(0.5)).unwrap(),
            Shape::from_mesh(&polyhedron).unwrap(),
            Shape::from_mesh(&hull).unwrap(),
        ];
        assert!(shapes[2].climb.is_some(), "a large hull");
        let (mut both, mut neither, mut apart, mut worst) = (0, 0, 0, [[0.0f64; 3]; 3]);
        for k in 0..20_000 {
            let s = &shapes[k % 3];
            let scale = 10f64.powf(2.0 * u() - 1.0) / s.radius;
            let mut corner = || Vec3::new(u() - 0.5, u() - 0.5, 0.2 * (u() - 0.5));
            let mut q = [corner(), corner(), corner()];
            if k % 7 == 0 {
                // A sliver: the third corner nearly on the first edge.
                q[2] = q[0] + (q[1] - q[0]) * u() + Vec3::new(0.0, 0.0, 1e-7);
            }
            let n = (q[1] - q[0]).cross(&(q[2] - q[0])).normalize();
            // Across the plane, within the body's size (a tenth of the cases grazing it),
            // anywhere about the triangle.
            let reach = if k % 10 == 0 { 1e-6 } else { 1.0 };
            let at = (q[0] + q[1] + q[2]) / 3.0
                + Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * 1.5
                + n * (2.0 * u() - 1.0) * s.radius * scale * reach;
            let turn = UnitQuaternion::from_euler_angles(7.0 * u(), 7.0 * u(), 7.0 * u());
            let b = s.posed(&at, &turn, scale);
            let radius = s.radius * scale;
            let sides = side_planes(&q, &n);
            // The prism is as deep as B is wide: B may not reach below it (one that met the
            // plane cannot; one wholly behind it, beyond it, meets only the prism's part).
            let d = n.dot(&q[0]);
            let lowest = (0..b.vertex_count(s)).map(|i| n.dot(&b.vertex(s, i)) - d);
            if lowest.fold(f64::INFINITY, f64::min) < -2.0 * radius {
                continue;
            }
            let clipped = facet_overlap_with(&q, &n, &sides, 2.0 * radius, s, &b);
            let behind = overlap_behind_facet(s, &b, &n, d, &sides);
            // The plane's and GJK's certificates that B misses the prism hold.
            let reach = reach_along(s, &b, &-n) + d;
            if reach <= 0.0 || apart_from_prism(s, &b, &q, &n, reach, 0.0) {
                apart += 1;
                assert!(
                    clipped.is_none_or(|(v, ..)| v < 1e-14 * crate::math::cube(radius)),
                    "case {k}: shown apart, yet {clipped:?}"
                );
            }
            match (clipped, behind) {
                (Some((v, c, cap)), Some((w, x, cap2))) => {
                    both += 1;
                    // Against the body's size: a grazing piece's centroid and cap are as
                    // exact as its corners, not relative to its own tiny size.
                    let errs = [
                        (v - w).abs() / crate::math::cube(radius),
                        (c - x).norm() / radius,
                        (cap - cap2).norm() / (radius * radius),
                    ];
                    // Looser for B wholly behind the plane (its faces' terms are taken about a
                    // point on the plane up to 2r away, and cancel to the piece's size) and for
                    // a sliver's centroid (1e-7 wide, its normal is known to 1e-9 from the
                    // cross product of two nearly parallel edges; its prism, 2r deep, to 1e-9
                    // r: seen to 7e-8 r apart, the pieces' volumes to 1e-17 r^3).
                    let (class, tol) = match (k % 7 == 0, cap.norm() > 0.0) {
                        (true, _) => (2, [1e-12, 1e-6, 1e-12]),
                        (false, false) => (1, [1e-10; 3]),
                        (false, true) => (0, [1e-12; 3]),
                    };
                    for (e, w) in errs.iter().zip(worst[class].iter_mut()) {
                        *w = w.max(*e);
                    }
                    assert!(
                        errs.iter().zip(tol).all(|(&e, t)| e < t),
                        "case {k}: errs {errs:?} radius {radius:e} volume {v:e} vs {w:e}, centroid {c:?} vs {x:?}, cap \
                         {cap:?} vs {cap2:?}"
                    );
                }
                (None, None) => neither += 1,
                // One finds what the other's rounding lost: a piece of no size.
                (Some((v, ..)), None) | (None, Some((v, ..))) => {
                    assert!(
                        v < 1e-14 * crate::math::cube(radius),
                        "case {k}: {clipped:?} vs {behind:?}"
                    );
                }
            }
        }
        assert!(
            both > 3000 && neither > 3000 && apart > 1000,
            "{both} overlapping, {neither} not ({apart} shown apart by GJK): too few to test"
        );
        eprintln!("worst relative differences (volume, centroid, cap); B meeting the plane, B wholly behind it, slivers: {worst:?}; {apart} shown apart by GJK");
    }

    /// A tube of facets around the z axis, its nodes jittered (no two triangles alike, none
    /// flat with its neighbours), facing in.
    fn bumpy_tube(around: usize, rings: usize, rng: &mut impl rand::RngCore) -> Wall {
        let mut jitter = || 0.1 * (crate::math::unit_f64(rng.next_u64()) - 0.5);
        let mut nodes = Vec::new();
        for h in 0..=rings {
            for a in 0..around {
                let t = std::f64::consts::TAU * (a as f64 + jitter()) / around as f64;
                let r = 1.0 + jitter();
                nodes.push(Vec3::new(
                    r * t.cos(),
                    r * t.sin(),
                    h as f64 * 0.3 + jitter(),
                ));
            }
        }
        let id = |a: usize, h: usize| (h * around + a % around) as u32;
        let mut tris = Vec::new();
        for h in 0..rings {
            for a in 0..around {
                tris.push([id(a, h), id(a, h + 1), id(a + 1, h + 1)]);
                tris.push([id(a, h), id(a + 1, h + 1), id(a + 1, h)]);
            }
        }
        Wall::facets(nodes, tris)
    }

    /// An Ab_3-like hull (a tangent-plane polyhedron subdivided three times, a climbing hull)
    /// and a small one (the tangent-plane polyhedron itself), each with the scale that gives
    /// it a bounding radius of 0.2 (a fifth of the tube's).
    fn hulls() -> [(Shape, f64); 2] {
        use crate::geometry::polygen::{generate, Params};
        let params = Params {
            faces: 9,
            ..Default::default()
        };
        let mesh = generate(&params, 3, 0).unwrap().mesh;
        let topo = mesh.topology(None).unwrap();
        let large = crate::geometry::subdiv::subdivide(&mesh, &topo, 3);
        let (a, b) = (
            Shape::from_mesh(&large).unwrap(),
            Shape::from_mesh(&mesh).unwrap(),
        );
        assert!(a.climb.is_some() && b.climb.is_none());
        let (ra, rb) = (a.radius, b.radius);
        [(a, 0.2 / ra), (b, 0.2 / rb)]
    }

    /// A tube of facets about the z axis, radius 1, from z = 0 to 2.4: 24 nodes a ring, 9
    /// rings, the particles inside.
    fn tube() -> Wall {
        let (around, rings) = (24, 8);
        let mut nodes = Vec::new();
        for h in 0..=rings {
            for a in 0..around {
                let t = std::f64::consts::TAU * a as f64 / around as f64;
                nodes.push(Vec3::new(t.cos(), t.sin(), h as f64 * 0.3));
            }
        }
        let id = |a: usize, h: usize| (h * around + a % around) as u32;
        let mut tris = Vec::new();
        for h in 0..rings {
            for a in 0..around {
                tris.push([id(a, h), id(a, h + 1), id(a + 1, h + 1)]);
                tris.push([id(a, h), id(a + 1, h + 1), id(a + 1, h)]);
            }
        }
        Wall::facets(nodes, tris)
    }

    /// Follows body `s` (scaled by `scale`) through `steps` steps, posed by `pose(k)` against
    /// `wall(k)`, touching it as the step does (with the facet set the last step kept), afresh
    /// (a new set) and by the walk over every triangle (no grid): the three contacts agree to
    /// the bit at every step. Returns how many steps kept the set, made a new one, touched.
    fn follow(
        s: &Shape,
        scale: f64,
        steps: usize,
        wall: impl Fn(usize) -> Wall,
        pose: impl Fn(usize) -> (Vec3, UnitQuaternion<f64>),
    ) -> (usize, usize, usize) {
        let r = s.radius * scale;
        let mut kept: Option<Vec<u32>> = None;
        let (mut kept_steps, mut new_steps, mut touching) = (0, 0, 0);
        let mut grid: Option<FacetGrid> = None;
        for k in 0..steps {
            let w = wall(k);
            // Kept while it fits the nodes, as the world keeps it.
            FacetGrid::refresh(&mut grid, &w, r);
            let grid = grid.as_ref().expect("a facet wall has a grid");
            let (at, turn) = pose(k);
            let b = s.posed(&at, &turn, scale);
            let (with, found) = w.touch_kept(s, &b, r, kept.as_deref(), Some(grid));
            let (fresh, _) = w.touch_kept(s, &b, r, None, Some(grid));
            let (walked, _) = w.touch_kept(s, &b, r, None, None);
            for other in [&fresh, &walked] {
                match (&with, other) {
                    (None, None) => {}
                    (Some(x), Some(y)) => {
                        assert_eq!(x.overlap, y.overlap, "step {k}");
                        assert_eq!(x.node_weights, y.node_weights, "step {k}");
                        assert_eq!(x.node_pushes, y.node_pushes, "step {k}");
                        assert_eq!((x.velocity, x.couple), (y.velocity, y.couple), "step {k}");
                    }
                    _ => panic!(
                        "step {k}: kept {}, other {}",
                        with.is_some(),
                        other.is_some()
                    ),
                }
            }
            // As the world keeps it, touching or not (a body near the wall keeps its set in
            // the world's near sets): a new set replaces the last.
            match found {
                WallFound::Kept => kept_steps += 1,
                WallFound::New(w) => {
                    new_steps += 1;
                    kept = Some(w);
                }
                WallFound::None => kept = None,
            }
            touching += usize::from(with.is_some());
        }
        (kept_steps, new_steps, touching)
    }

    /// Where to put body `s` (scaled, turned) so that it reaches `out` beyond the tube's
    /// radius at angle `t` and height `z`: its farthest point outwards there (the tube's
    /// polygon lies inside its circle, so the body overlaps the facets by about that much and
    /// the polygon's sagitta, 0.9 % of the radius).
    fn pressed(
        s: &Shape,
        scale: f64,
        turn: &UnitQuaternion<f64>,
        t: f64,
        z: f64,
        out: f64,
    ) -> Vec3 {
        let dir = Vec3::new(t.cos(), t.sin(), 0.0);
        let reach = (s.vertices.iter())
            .map(|v| dir.dot(&(turn * (v * scale))))
            .fold(f64::NEG_INFINITY, f64::max);
        dir * (1.0 + out - reach) + Vec3::z() * z
    }

    /// A named hard case: a body sliding along the sleeve across many facets (a sixteenth of
    /// the circumference, four triangles, and a third of a ring up), pressed into it: kept
    /// sets agree with new ones and with the walk at every step, and most steps keep theirs.
    #[test]
    fn a_body_sliding_along_the_sleeve_across_many_facets_keeps_the_walk_s_contact() {
        for (s, scale) in hulls().iter().map(|(s, k)| (s, *k)) {
            let turn = UnitQuaternion::from_euler_angles(0.3, 1.1, -0.4);
            let (kept, new, touching) = follow(
                s,
                scale,
                400,
                |_| tube(),
                |k| {
                    let t = 0.2 + 0.4 * k as f64 / 400.0;
                    (
                        pressed(s, scale, &turn, t, 1.0 + 0.1 * k as f64 / 400.0, 0.0),
                        turn,
                    )
                },
            );
            assert!(touching >= 390, "{touching} steps touching");
            assert!(kept > new, "{kept} kept, {new} new");
        }
    }

    /// A named hard case: a body turning in place against the sleeve, so that faces that
    /// were not in its set come into a prism; the set is made anew before they do.
    #[test]
    fn a_body_turning_so_that_new_faces_enter_the_prism_keeps_the_walk_s_contact() {
        for (s, scale) in hulls().iter().map(|(s, k)| (s, *k)) {
            let first = UnitQuaternion::from_euler_angles(0.3, 1.1, -0.4);
            let at = pressed(s, scale, &first, 0.7, 1.2, 0.0);
            let (kept, new, touching) = follow(
                s,
                scale,
                400,
                |_| tube(),
                |k| {
                    // About an axis through the centre, across the sleeve's normal.
                    let turn =
                        UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 0.6 * k as f64 / 400.0)
                            * first;
                    (at, turn)
                },
            );
            assert!(touching >= 390, "{touching} steps touching");
            assert!(kept > 0 && new > 1, "{kept} kept, {new} new");
        }
    }

    /// A named hard case: the facets under a body stretched and tilted as the sleeve bulges
    /// (the nodes near the body move out, by up to a tenth of the body's size, each a little
    /// every step): kept sets agree with new ones and with the walk.
    #[test]
    fn facets_stretched_and_tilted_by_bulging_keep_the_walk_s_contact() {
        for (s, scale) in hulls().iter().map(|(s, k)| (s, *k)) {
            let r = s.radius * scale;
            let turn = UnitQuaternion::from_euler_angles(0.3, 1.1, -0.4);
            let at = pressed(s, scale, &turn, 0.7, 1.2, 0.0);
            let bulge = move |k: usize| {
                let mut w = tube();
                if let WallKind::Facets { nodes, .. } = &mut w.kind {
                    for x in nodes.iter_mut() {
                        let near = (-(*x - at).norm_squared() / 0.05).exp();
                        let out = Vec3::new(x.x, x.y, 0.0).normalize();
                        *x += out * (0.1 * r * near * k as f64 / 300.0);
                    }
                }
                w
            };
            let (kept, new, touching) = follow(s, scale, 300, bulge, |k| {
                (
                    at + Vec3::new(at.x, at.y, 0.0).normalize() * (0.05 * r * k as f64 / 300.0),
                    turn,
                )
            });
            assert!(touching >= 290, "{touching} steps touching");
            assert!(kept > 0 && new > 1, "{kept} kept, {new} new");
        }
    }

    /// A named hard case: a set made invalid by the nodes' motion alone (the body at rest):
    /// the nodes near it jump by more than the band every 20 steps and creep between; each
    /// jump makes a new set, and every step agrees with the walk.
    #[test]
    fn a_set_invalidated_by_the_nodes_motion_is_made_anew() {
        for (s, scale) in hulls().iter().map(|(s, k)| (s, *k)) {
            let r = s.radius * scale;
            let turn = UnitQuaternion::from_euler_angles(0.3, 1.1, -0.4);
            let at = pressed(s, scale, &turn, 0.7, 1.2, 0.0);
            let moved = move |k: usize| {
                let mut w = tube();
                let shift = 0.05 * r * (k / 20) as f64 + 1e-5 * r * (k % 20) as f64;
                if let WallKind::Facets { nodes, .. } = &mut w.kind {
                    for x in nodes.iter_mut() {
                        if (*x - at).norm() < 0.5 {
                            *x += Vec3::new(x.x, x.y, 0.0).normalize() * -shift;
                        }
                    }
                }
                w
            };
            let (kept, new, touching) = follow(s, scale, 100, moved, |_| (at, turn));
            assert_eq!(touching, 100);
            assert!(new >= 5 && kept >= 50, "{kept} kept, {new} new");
        }
    }

    /// A named hard case: a body at the seam where the sleeve meets a platen (the tube's end,
    /// z = 0: the last ring of triangles, whose prisms end there), sliding along it half in,
    /// half beyond the sleeve's end.
    #[test]
    fn a_body_at_the_seam_of_the_sleeve_and_a_platen_keeps_the_walk_s_contact() {
        for (s, scale) in hulls().iter().map(|(s, k)| (s, *k)) {
            let r = s.radius * scale;
            let turn = UnitQuaternion::from_euler_angles(0.3, 1.1, -0.4);
            let (kept, new, touching) = follow(
                s,
                scale,
                300,
                |_| tube(),
                |k| {
                    let t = 0.2 + 0.6 * k as f64 / 300.0;
                    let z = 0.5 * r - 0.7 * r * k as f64 / 300.0;
                    (pressed(s, scale, &turn, t, z, 0.0), turn)
                },
            );
            assert!(touching >= 200, "{touching} steps touching");
            assert!(kept > new, "{kept} kept, {new} new");
        }
    }

    /// A named hard case: a body that comes near the sleeve without touching it, presses into
    /// it and draws back (from a fifth of its radius short of the tube's circle to a twentieth
    /// beyond, the facets lying up to 0.0086 inside it): the set it made while near is kept
    /// into the contact and out of it, as the world keeps near bodies' sets, and every step
    /// agrees with a new set and with the walk.
    #[test]
    fn a_body_near_the_sleeve_keeps_its_set_before_and_after_it_touches() {
        for (s, scale) in hulls().iter().map(|(s, k)| (s, *k)) {
            let r = s.radius * scale;
            let turn = UnitQuaternion::from_euler_angles(0.3, 1.1, -0.4);
            let steps = 300;
            let (kept, new, touching) = follow(
                s,
                scale,
                steps,
                |_| tube(),
                |k| {
                    let phase = k as f64 / steps as f64;
                    let out = r * (0.25 * (1.0 - (2.0 * phase - 1.0).abs()) - 0.2);
                    (pressed(s, scale, &turn, 0.7, 1.2, out), turn)
                },
            );
            assert!((30..270).contains(&touching), "{touching} steps touching");
            assert_eq!(kept + new, steps, "every step has a set, touching or not");
            assert!(kept > 5 * new, "{kept} kept, {new} new");
        }
    }

    /// The grid the step uses changes no facet contact, to the bit, and rules out only bodies
    /// that touch nothing: bodies from 1/50 to the size of the tube's triangles, in and across
    /// its surface and its floor's, the grid made for the largest of them.
    #[test]
    fn a_facet_grid_changes_no_contact_and_rules_out_only_bodies_that_touch_nothing() {
        use rand::{RngCore, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut u = move || crate::math::unit_f64(rng.next_u64());
        let mut tube_rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let s = Shape::from_mesh(&cube(0.5)).unwrap();
        let scales = [0.02, 0.1, 0.3];
        let largest = s.radius * 0.3;
        for wall in [bumpy_tube(24, 8, &mut tube_rng), floor(7)] {
            let grid = FacetGrid::of(&wall, largest).expect("a facet wall has a grid");
            let tube = matches!(&wall.kind, WallKind::Facets { nodes, .. } if nodes.len() > 100);
            let (mut touching, mut out) = (0, 0);
            for k in 0..3000 {
                let scale = scales[k % 3];
                // Near the tube's surface (or the floor), up to a few sizes in or out.
                let at = if tube {
                    let (t, r) = (u() * std::f64::consts::TAU, 1.0 + 0.6 * (u() - 0.5));
                    Vec3::new(r * t.cos(), r * t.sin(), 2.6 * u() - 0.1)
                } else {
                    Vec3::new(5.0 * u() - 2.5, 5.0 * u() - 2.5, 0.6 * (u() - 0.5))
                };
                let turn = UnitQuaternion::from_euler_angles(7.0 * u(), 7.0 * u(), 7.0 * u());
                let b = s.posed(&at, &turn, scale);
                let r = s.radius * scale;
                let (all, _) = wall.touch_kept(&s, &b, r, None, None);
                let (near, _) = wall.touch_kept(&s, &b, r, None, Some(&grid));
                match (&all, &near) {
                    (None, None) => {}
                    (Some(x), Some(y)) => {
                        assert_eq!(x.overlap, y.overlap, "pose {k}");
                        assert_eq!(x.node_weights, y.node_weights, "pose {k}");
                        assert_eq!((x.velocity, x.couple), (y.velocity, y.couple), "pose {k}");
                    }
                    _ => panic!("pose {k}: with the grid {}", near.is_some()),
                }
                touching += usize::from(all.is_some());
                if !wall.may_touch(&b.lo, &b.hi, Some(&grid)) {
                    assert!(all.is_none(), "pose {k}: ruled out, yet touching");
                    out += 1;
                }
            }
            assert!(
                touching > 300 && out > 300,
                "{touching} touching, {out} ruled out: too few to test"
            );
        }
    }

    /// A named hard case: a grid kept while the nodes move (each 1e-4 a step along a random
    /// direction of its own, so that the planes tilt steadily): while it fits the nodes,
    /// every triangle's prism box lies within its box in the grid, and it stops fitting
    /// before the nodes have moved beyond its skin.
    #[test]
    fn a_kept_grid_holds_every_prism_while_it_fits_the_nodes() {
        use rand::{RngCore, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut u = move || crate::math::unit_f64(rng.next_u64());
        let mut tube_rng = rand_chacha::ChaCha8Rng::seed_from_u64(6);
        let mut wall = bumpy_tube(24, 8, &mut tube_rng);
        let radius = 0.1;
        let grid = FacetGrid::of(&wall, radius).expect("a facet wall has a grid");
        let depth = wall.prism_depth(radius);
        // Each node's own direction, kept: neighbours moving apart tilt the planes steadily.
        let dirs: Vec<Vec3> = match &wall.kind {
            WallKind::Facets { nodes, .. } => (nodes.iter())
                .map(|_| Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5).normalize())
                .collect(),
            _ => unreachable!(),
        };
        let mut kept = 0;
        while grid.fits(&wall, radius) {
            kept += 1;
            let WallKind::Facets {
                nodes, triangles, ..
            } = &mut wall.kind
            else {
                unreachable!()
            };
            for (k, t) in triangles.iter().enumerate() {
                let (lo, hi) = prism_box(&t.map(|i| nodes[i as usize]), depth, radius);
                let (glo, ghi) = grid.boxes[k];
                assert!(
                    (0..3).all(|j| glo[j] <= lo[j] && hi[j] <= ghi[j]),
                    "step {kept}: triangle {k}'s prism beyond its box in the grid"
                );
            }
            for (x, dir) in nodes.iter_mut().zip(&dirs) {
                *x += dir * 1e-4;
            }
            assert!(
                kept < 10_000,
                "the grid fits nodes that moved beyond its skin"
            );
        }
        assert!(kept >= 10, "the grid fitted {kept} steps only");
        assert!(FacetGrid::of(&wall, radius).is_some_and(|g| g.fits(&wall, radius)));
    }

    /// A floor z = 0 of two triangles over [-2, 2]^2, or of many small ones.
    fn floor(cells: usize) -> Wall {
        let mut nodes = Vec::new();
        let h = 4.0 / cells as f64;
        for j in 0..=cells {
            for i in 0..=cells {
                nodes.push(Vec3::new(-2.0 + i as f64 * h, -2.0 + j as f64 * h, 0.0));
            }
        }
        Wall::facets(nodes, grid_triangles(cells, cells))
    }

    #[test]
    fn facets_under_a_face_act_as_one_plane() {
        // A unit cube sunk 0.01 into a floor, straddling many facets at odd offsets: the
        // contact equals the plane's, whatever the facets under it.
        let plane = Wall::plane(Vec3::zeros(), Vec3::z());
        for cells in [1, 3, 7] {
            let wall = floor(cells);
            for x in [0.0, 0.13, 0.5, -0.77] {
                let (s, b) = cube_at(Vec3::new(x, 0.31 * x, 0.49));
                let r = s.radius;
                let f = wall.touch(&s, &b, r).unwrap().overlap;
                let p = plane.touch(&s, &b, r).unwrap().overlap;
                assert_relative_eq!(f.volume, p.volume, max_relative = 1e-9);
                assert_relative_eq!(f.depth(), 0.01, max_relative = 1e-9);
                assert_relative_eq!(f.normal(), Vec3::z(), epsilon = 1e-12);
                assert_relative_eq!(f.centroid, p.centroid, epsilon = 1e-9);
            }
        }
    }

    #[test]
    fn facet_node_weights_share_the_force_and_sum_to_one() {
        let wall = floor(2);
        let (s, b) = cube_at(Vec3::new(0.3, -0.2, 0.49));
        let hit = wall.touch(&s, &b, s.radius).unwrap();
        let total: f64 = hit.node_weights.iter().map(|(_, w)| w).sum();
        assert_relative_eq!(total, 1.0, epsilon = 1e-12);
        // The weighted node positions give back the contact point (in the floor's plane).
        let WallKind::Facets { nodes, .. } = &wall.kind else {
            unreachable!()
        };
        let p: Vec3 = hit
            .node_weights
            .iter()
            .map(|&(k, w)| nodes[k as usize] * w)
            .sum();
        assert_relative_eq!(p.xy(), hit.overlap.centroid.xy(), epsilon = 1e-9);
    }

    #[test]
    fn cylinder_pushes_inwards_and_misses_bodies_well_inside() {
        let wall = Wall::cylinder(Vec3::zeros(), Vec3::z(), 5.0, 10.0, 256);
        let (s, b) = cube_at(Vec3::new(0.0, 0.0, 5.0));
        assert!(wall.touch(&s, &b, s.radius).is_none());
        // A cube at azimuth 0 (a segment corner) pressed 0.01 into the wall: a face against
        // two segments, nearly flat.
        for angle in [0.0, 0.3, 1.234, -2.5] {
            let rot = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), angle);
            let p = rot * Vec3::new(5.0 - 0.49, 0.0, 5.0);
            let b = s.posed(&p, &rot, 1.0);
            let o = wall.touch(&s, &b, s.radius).unwrap().overlap;
            let inward = -(rot * Vec3::x());
            assert!(
                (o.normal() - inward).norm() < 0.01,
                "normal {:?}",
                o.normal()
            );
            // Sagitta of 0.5 over radius 5 is 0.025: the depth is 0.01 less up to that.
            assert!((o.depth() - 0.01).abs() < 0.025, "depth {}", o.depth());
        }
    }

    #[test]
    fn a_cylinder_touches_as_its_facets_do_for_bodies_across_its_seam_and_in_small_tubes() {
        // The cylinder builds only the facets within a body's angles; the same polygon as
        // triangle facets builds them all. Long thin bodies (a box of half-widths 0.6, 0.1, 0.1, tilted) reach
        // over many facets, cross the seam at angle 0, and in the small tube hold its axis.
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let rod =
            Shape::from_mesh(&crate::geometry::mesh::cuboid(Vec3::new(0.6, 0.1, 0.1))).unwrap();
        let (mut hits, mut spots) = (0, 0);
        for (r_cyl, segments) in [(1.0, 32u32), (0.25, 16)] {
            let cyl = Wall::cylinder(Vec3::zeros(), Vec3::z(), r_cyl, 2.0, segments);
            let step = std::f64::consts::TAU / f64::from(segments);
            let ring = |j: u32, z: f64| {
                let a = f64::from(j % segments) * step;
                Vec3::new(r_cyl * a.cos(), r_cyl * a.sin(), z)
            };
            let nodes: Vec<Vec3> = (0..segments)
                .flat_map(|j| [ring(j, 0.0), ring(j, 2.0)])
                .collect();
            let triangles: Vec<[u32; 3]> = (0..segments)
                .flat_map(|j| {
                    let (a, b, c, d) = (
                        2 * j,
                        2 * j + 1,
                        2 * ((j + 1) % segments) + 1,
                        2 * ((j + 1) % segments),
                    );
                    [[a, b, c], [a, c, d]]
                })
                .collect();
            let facets = Wall::facets(nodes, triangles);
            for _ in 0..400 {
                let angle =
                    rng.random_range(-0.4..0.4f64) + if rng.random_bool(0.5) { 0.0 } else { 2.0 };
                let rho = rng.random_range(0.0..r_cyl);
                let p = Vec3::new(rho * angle.cos(), rho * angle.sin(), 1.0);
                let axis = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5);
                let rot = UnitQuaternion::from_scaled_axis(axis * 6.0);
                let b = rod.posed(&p, &rot, 1.0);
                let (x, y) = (
                    cyl.touch(&rod, &b, rod.radius),
                    facets.touch(&rod, &b, rod.radius),
                );
                assert_eq!(x.is_some(), y.is_some(), "at {p:?}");
                if let (Some(hx), Some(hy)) = (x, y) {
                    hits += 1;
                    let (x, y) = (hx.overlap, hy.overlap);
                    assert_relative_eq!(x.volume, y.volume, max_relative = 1e-9);
                    // The same spots, but each pushing along the radius through its
                    // centroid, so the force makes no moment about the axis (the facets'
                    // normal, their area-weighted mean, strays from it where a spot spans
                    // many facets: by up to 17 degrees for these rods).
                    let f = x.normal() * x.depth();
                    let about_axis = x.centroid.cross(&f) + hx.couple;
                    assert!(about_axis.z.abs() < 1e-12, "{about_axis:?}");
                    assert_eq!(hx.couple == Vec3::zeros(), hy.couple == Vec3::zeros());
                    if hx.couple == Vec3::zeros() {
                        // One spot: the facets' volume, centroid and area.
                        assert_relative_eq!(x.centroid, y.centroid, epsilon = 1e-9);
                        assert_relative_eq!(x.area_b.norm(), y.area_b.norm(), epsilon = 1e-9);
                        let radial = Vec3::new(x.centroid.x, x.centroid.y, 0.0).normalize();
                        assert_relative_eq!(x.normal(), -radial, epsilon = 1e-12);
                    } else {
                        spots += 1;
                    }
                }
            }
        }
        assert!(hits > 200, "{hits} contacts");
        assert!(spots > 10, "{spots} contacts in separate spots");
    }

    /// The wall's push on a body (unit stiffness: the force is `depth x normal`) and its moment
    /// about the body's centroid, at the body's pose moved by `q` (translation, then rotation
    /// vector).
    fn push(
        wall: &Wall,
        s: &Shape,
        pos: &Vec3,
        rot: &UnitQuaternion<f64>,
        q: &[f64; 6],
    ) -> [f64; 6] {
        let p = pos + Vec3::new(q[0], q[1], q[2]);
        let r = UnitQuaternion::from_scaled_axis(Vec3::new(q[3], q[4], q[5])) * rot;
        let hit = wall
            .touch(s, &s.posed(&p, &r, 1.0), s.radius)
            .expect("a contact");
        let f = hit.overlap.normal() * hit.overlap.depth();
        let m = (hit.overlap.centroid - p).cross(&f) + hit.couple;
        [f.x, f.y, f.z, m.x, m.y, m.z]
    }

    /// The largest antisymmetric (circulatory) part of the stiffness of [`push`], over its
    /// largest entry (lengths in units of `size`, so translations and rotations compare).
    fn circulation(
        wall: &Wall,
        s: &Shape,
        pos: &Vec3,
        rot: &UnitQuaternion<f64>,
        size: f64,
    ) -> f64 {
        let h = 1e-7 * size;
        let step = |k: usize| if k < 3 { h } else { h / size };
        let unit = |k: usize| if k < 3 { 1.0 } else { 1.0 / size };
        let mut k = [[0.0; 6]; 6];
        for j in 0..6 {
            let (mut up, mut down) = ([0.0; 6], [0.0; 6]);
            up[j] = step(j);
            down[j] = -step(j);
            let (a, b) = (push(wall, s, pos, rot, &up), push(wall, s, pos, rot, &down));
            for i in 0..6 {
                k[i][j] = (a[i] - b[i]) / (2.0 * step(j)) * unit(i) * unit(j);
            }
        }
        let pairs = || (0..6).flat_map(|i| (0..6).map(move |j| (i, j)));
        let largest = pairs().map(|(i, j)| k[i][j].abs()).fold(0.0, f64::max);
        let curl = (pairs())
            .map(|(i, j)| (k[i][j] - k[j][i]).abs() / 2.0)
            .fold(0.0, f64::max);
        curl / largest
    }

    #[test]
    fn a_plate_bridging_the_cylinder_pushes_at_both_ends_as_a_gradient() {
        // A plate 0.6 long lying across the inside of a tube of radius 1 touches it at its two
        // ends, facets apart (the middle clears the wall by the chord's sagitta, 0.045). Each
        // end pushes as a contact of its own, along the radius: the push is then nearly a
        // gradient (4.9 % circulatory here, the linear law's own for the tilted plate's
        // edges). One push of the summed volume and area at the joint centroid was not: 52 %,
        // and it fed energy into a particle wedged against a pack specimen's cylinder
        // (docs/models/walls.md, "Spots").
        let plate =
            Shape::from_mesh(&crate::geometry::mesh::cuboid(Vec3::new(0.3, 0.02, 0.1))).unwrap();
        let cyl = Wall::cylinder(Vec3::new(0.0, 0.0, -1.0), Vec3::z(), 1.0, 2.0, 128);
        let inscribed = (std::f64::consts::PI / 128.0).cos();
        // Tilted and turned a little, so the two ends sink by different depths.
        // (The shape's vertices are in its principal frame: `frame_in_mesh` turns them back
        // to the mesh's axes.)
        let rot = UnitQuaternion::from_scaled_axis(Vec3::new(0.5, 0.3, 0.02)) * plate.frame_in_mesh;
        let mut pos = Vec3::new(0.0, inscribed - 0.067, 0.0);
        // Pushed out until both ends touch (the couple of two spots), then 1e-4 further.
        while (cyl.touch(&plate, &plate.posed(&pos, &rot, 1.0), plate.radius))
            .is_none_or(|hit| hit.couple == Vec3::zeros())
        {
            pos.y += 1e-5;
            assert!(pos.y < 1.0, "no pose with both ends on the wall");
        }
        pos.y += 1e-4;
        let hit = cyl
            .touch(&plate, &plate.posed(&pos, &rot, 1.0), plate.radius)
            .unwrap();
        assert!(hit.couple.norm() > 0.0, "two spots, a couple");
        // The pushes are radial: no moment about the axis.
        let f = hit.overlap.normal() * hit.overlap.depth();
        let about_axis = (hit.overlap.centroid - Vec3::new(0.0, 0.0, -1.0)).cross(&f) + hit.couple;
        assert!(
            about_axis.z.abs() < 1e-12,
            "moment about the axis {:e}",
            about_axis.z
        );
        let c = circulation(&cyl, &plate, &pos, &rot, 0.6);
        assert!(c < 0.1, "circulatory part {c:.3}");
    }

    #[test]
    fn moving_nodes_move_the_contact_velocity_and_the_wall() {
        let mut wall = floor(1);
        if let WallKind::Facets {
            node_velocities, ..
        } = &mut wall.kind
        {
            node_velocities
                .iter_mut()
                .for_each(|v| *v = Vec3::new(0.0, 0.0, 0.5));
        }
        let (s, b) = cube_at(Vec3::new(0.1, 0.1, 0.49));
        let hit = wall.touch(&s, &b, s.radius).unwrap();
        assert_relative_eq!(hit.velocity, Vec3::new(0.0, 0.0, 0.5), epsilon = 1e-12);
        wall.advance(0.1);
        let hit = wall.touch(&s, &b, s.radius).unwrap();
        assert_relative_eq!(hit.overlap.depth(), 0.06, max_relative = 1e-9);
    }
}
