//! A flexible membrane: a facet wall whose nodes move under the particles' contact forces, a
//! pressure on its outer side and its own elasticity (the triaxial test's rubber sleeve).
//!
//! The membrane is the facet wall's triangulated surface ([`WallKind::Facets`]), the particles
//! on the side its triangles' normals point to. Each node is a point mass; at the end of every
//! step it takes
//! - the contact forces the particles pushed on it this step (the wall's `node_forces`);
//! - the pressure: a follower load `p a / 3` per node of each triangle, `a` the triangle's area
//!   vector as it is now (towards the particles): the confining pressure acts on the outer side;
//! - the elastic forces of constant-strain triangles in plane stress (membrane action, no
//!   bending), from the Green-Lagrange strain of each triangle against its rest shape and the
//!   St Venant-Kirchhoff law `S = D E`, `D` the plane-stress stiffness of `young` and `poisson`
//!   times the `thickness`: exact for any rigid motion, and for small strains the linear CST;
//! - local damping as the bodies get it (the material's `damping`).
//!
//! Nodes held by a wall (pins: a membrane's end rings sealed to the platens) move with that
//! wall's velocity instead (`sealed`), or only along its normal and freely in its plane (not
//! sealed: ends that slide on the platens).
//!
//! Energy: the membrane's kinetic and elastic energy, the pressure's work on its free motion and
//! the damping's dissipation enter the world's audit ([`crate::dem::energy::Energy`]); what a
//! pinning wall does on the membrane through its pinned nodes counts as that wall's work, and
//! the particles' contacts with the membrane are internal (their wall work is not counted).

use crate::dem::wall::{Wall, WallKind};
use crate::math::Vec3;
use rayon::prelude::*;

/// A node held by a wall.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pin {
    pub node: u32,
    pub wall: u32,
}

/// A membrane's material, loads and contacts (SI units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sheet {
    /// Young's modulus, Pa.
    pub young: f64,
    /// Poisson's ratio, in [0, 0.5].
    pub poisson: f64,
    /// Thickness, m.
    pub thickness: f64,
    /// Pressure on the outer side, Pa, pushing the membrane towards the particles (negative:
    /// pulling it away).
    pub pressure: f64,
    /// Mass of each node, kg.
    pub node_mass: f64,
    /// Stiffness of the particles' contacts with the membrane, N/m^3: each facet a Winkler
    /// foundation, the pressure on it this times the local penetration (a sheet of modulus
    /// `E` and thickness `t` compressed: `E / t`); and a shear stiffness, N/m^3 likewise, that
    /// no law reads: the contacts are frictionless (a scene with wall friction beside a
    /// membrane is refused).
    pub kn: f64,
    pub ks: f64,
    /// Local damping of the nodes (`None`: the material's, as the bodies).
    pub damping: Option<f64>,
    /// How deep behind the membrane a body is looked for, m: its contacts are shallow (the
    /// pressure over the stiffness), so bodies farther in are not tested against it.
    pub reach: f64,
}

impl Sheet {
    /// Checks every parameter.
    pub fn check(&self) -> Result<(), MembraneError> {
        let checks: [(&'static str, f64, bool, &'static str); 8] = [
            (
                "young",
                self.young,
                self.young > 0.0,
                "a positive modulus in Pa",
            ),
            (
                "poisson",
                self.poisson,
                (0.0..=0.5).contains(&self.poisson),
                "a Poisson's ratio in [0, 0.5]",
            ),
            (
                "thickness",
                self.thickness,
                self.thickness > 0.0,
                "a positive thickness in m",
            ),
            ("pressure", self.pressure, true, "a finite pressure in Pa"),
            (
                "node_mass",
                self.node_mass,
                self.node_mass > 0.0,
                "a positive mass in kg",
            ),
            (
                "kn",
                self.kn,
                self.kn > 0.0,
                "a positive stiffness in N/m^3",
            ),
            (
                "ks",
                self.ks,
                self.ks >= 0.0,
                "a stiffness of 0 or more in N/m^3",
            ),
            (
                "reach",
                self.reach,
                self.reach > 0.0,
                "a positive depth in m",
            ),
        ];
        if let Some(d) = self.damping {
            if !(0.0..1.0).contains(&d) {
                return Err(MembraneError::Param {
                    field: "damping",
                    rule: "in [0, 1)",
                    value: d,
                });
            }
        }
        match (checks.into_iter()).find(|&(_, v, ok, _)| !(ok && v.is_finite())) {
            Some((field, value, _, rule)) => Err(MembraneError::Param { field, rule, value }),
            None => Ok(()),
        }
    }
}

/// The membrane of a facet wall (see the module).
#[derive(Clone, Debug, PartialEq)]
pub struct Membrane {
    pub sheet: Sheet,
    /// Nodes held by walls.
    pub pins: Vec<Pin>,
    /// Pinned nodes move with their wall's velocity (true), or only along its normal.
    pub sealed: bool,
    /// Nodes not pinned are guided: each moves only along its rest position's direction from
    /// the membrane's axis, and along the axis with the two walls in proportion to its rest
    /// height between the membrane's ends (see [`Guide`]); `None`: free.
    pub guide: Option<Guide>,
    /// Node positions of the unstressed membrane, m.
    pub rest: Vec<Vec3>,
    /// Per triangle, the inverse of its rest edge matrix in its own plane, and its rest area.
    reference: Vec<Reference>,
    /// Per node, its triangles and its corner in each, in triangle order.
    corners: Vec<Vec<(u32, u8)>>,
    /// Per node, the pinning wall's index, or `u32::MAX`.
    pinned: Vec<u32>,
    /// Per node, with a guide: its free direction and its height's share between the ends.
    guides: Vec<(Vec3, f64)>,
}

/// How a cylindrical membrane's nodes are guided: along the z axis the nodes follow walls
/// `bottom` and `top` (the platens) in proportion to their rest heights between the rest
/// shape's lowest and highest node; across it each moves only along its rest direction from
/// the axis (through the rest nodes' mean in x and y). A guided membrane cannot fold, tangle
/// or wrap a particle; it bulges and sags into the voids between particles as the pressure and
/// its tension say.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Guide {
    pub bottom: u32,
    pub top: u32,
}

/// The share of the plane-stress law a wrinkled or slack triangle keeps (its energy is the
/// relaxed energy plus this share of the difference to the taut law's): enough to keep a
/// compressed triangle from collapsing, too little to carry a load.
pub const RESIDUAL: f64 = 0.01;

/// A triangle's rest shape: `dm_inv` maps its edges `(b - a, c - a)`, in a frame of its plane,
/// to the unit square; `area` its rest area.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Reference {
    dm_inv: [[f64; 2]; 2],
    area: f64,
}

/// What a membrane's step hands the world's energy audit, J.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MembraneEnergy {
    /// Kinetic energy of the free motion (velocities at the half step).
    pub kinetic: f64,
    /// Elastic energy at the nodes' positions this step.
    pub elastic: f64,
    /// Work of the pressure on the free motion over the step.
    pub pressure_work: f64,
    /// Energy the local damping took over the step.
    pub damping: f64,
    /// Work the pinning walls did on the membrane and its contacts over the step.
    pub wall_work: f64,
}

/// Why a membrane cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MembraneError {
    #[error("{field} must be {rule}, got {value}")]
    Param {
        field: &'static str,
        rule: &'static str,
        value: f64,
    },
    #[error("the rest shape has {rest} nodes, the wall {nodes}")]
    Nodes { rest: usize, nodes: usize },
    #[error("triangle {0} has no area in the rest shape")]
    Flat(usize),
    #[error("guide: {0}")]
    Guide(String),
    #[error("pin of node {node} on wall {wall}: {why}")]
    Pin { node: u32, wall: u32, why: String },
}

impl Membrane {
    /// A membrane of `sheet` on `triangles` of `rest` nodes (its unstressed shape); checks
    /// every parameter. `walls` is the number of walls a pin may name.
    pub fn new(
        sheet: Sheet,
        rest: Vec<Vec3>,
        triangles: &[[u32; 3]],
        pins: Vec<Pin>,
        sealed: bool,
        guide: Option<Guide>,
        walls: usize,
    ) -> Result<Membrane, MembraneError> {
        sheet.check()?;
        let mut reference = Vec::with_capacity(triangles.len());
        for (k, t) in triangles.iter().enumerate() {
            let [a, b, c] = t.map(|i| rest[i as usize]);
            let (e1, e2) = (b - a, c - a);
            let normal = e1.cross(&e2);
            let twice = normal.norm();
            if !(twice > 1e-12 * e1.norm_squared().max(e2.norm_squared())) {
                return Err(MembraneError::Flat(k));
            }
            let u = e1 / e1.norm();
            let v = (normal / twice).cross(&u);
            // The rest edges in the frame (u, v): columns (e1, e2).
            let dm = [[e1.dot(&u), e2.dot(&u)], [e1.dot(&v), e2.dot(&v)]];
            let det = dm[0][0] * dm[1][1] - dm[0][1] * dm[1][0];
            let dm_inv = [
                [dm[1][1] / det, -dm[0][1] / det],
                [-dm[1][0] / det, dm[0][0] / det],
            ];
            reference.push(Reference {
                dm_inv,
                area: 0.5 * twice,
            });
        }
        let mut corners = vec![Vec::new(); rest.len()];
        for (k, t) in triangles.iter().enumerate() {
            for (corner, &i) in t.iter().enumerate() {
                corners[i as usize].push((k as u32, corner as u8));
            }
        }
        let mut pinned = vec![u32::MAX; rest.len()];
        for p in &pins {
            let bad = |why: &str| MembraneError::Pin {
                node: p.node,
                wall: p.wall,
                why: why.into(),
            };
            let Some(slot) = pinned.get_mut(p.node as usize) else {
                return Err(bad("no such node"));
            };
            if p.wall as usize >= walls {
                return Err(bad("no such wall"));
            }
            if *slot != u32::MAX {
                return Err(bad("the node is pinned twice"));
            }
            *slot = p.wall;
        }
        let mut guides = Vec::new();
        if let Some(g) = guide {
            for (wall, which) in [(g.bottom, "bottom"), (g.top, "top")] {
                if wall as usize >= walls {
                    return Err(MembraneError::Guide(format!(
                        "the {which} wall {wall} does not exist"
                    )));
                }
            }
            let (lo, hi) = rest
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
                    (a.min(x.z), b.max(x.z))
                });
            let centre = rest.iter().sum::<Vec3>() / rest.len().max(1) as f64;
            for (i, x) in rest.iter().enumerate() {
                let out = Vec3::new(x.x - centre.x, x.y - centre.y, 0.0);
                let len = out.norm();
                if pinned[i] == u32::MAX && !(len > 0.0 && hi > lo) {
                    return Err(MembraneError::Guide(format!("node {i} is on the axis")));
                }
                let dir = if len > 0.0 { out / len } else { Vec3::zeros() };
                let frac = if hi > lo { (x.z - lo) / (hi - lo) } else { 0.0 };
                guides.push((dir, frac));
            }
        }
        Ok(Membrane {
            sheet,
            guide,
            guides,
            pins,
            sealed,
            rest,
            reference,
            corners,
            pinned,
        })
    }

    /// The plane-stress stiffness times the thickness: `(d11, d12, d33)` of
    /// `t E / (1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1 - nu) / 2]]`.
    fn stiffness(&self) -> (f64, f64, f64) {
        let d = self.sheet.thickness * self.sheet.young
            / (1.0 - self.sheet.poisson * self.sheet.poisson);
        (
            d,
            d * self.sheet.poisson,
            d * 0.5 * (1.0 - self.sheet.poisson),
        )
    }

    /// A bound on the stiffness of the membrane at any node, N/m: the largest eigenvalue of a
    /// constant-strain triangle's stiffness is at most `t A |D| sum_i |grad N_i|^2`
    /// (`|D| = E / (1 - nu)` for plane stress), summed over the node's triangles.
    pub fn node_stiffness(&self, triangles: &[[u32; 3]]) -> f64 {
        let norm_d = self.sheet.thickness * self.sheet.young / (1.0 - self.sheet.poisson);
        let per_triangle: Vec<f64> = (triangles.iter().zip(&self.reference))
            .map(|(t, r)| {
                let [a, b, c] = t.map(|i| self.rest[i as usize]);
                let edges =
                    (b - c).norm_squared() + (c - a).norm_squared() + (a - b).norm_squared();
                norm_d * edges / (4.0 * r.area)
            })
            .collect();
        (self.corners.iter())
            .map(|c| {
                c.iter()
                    .map(|&(t, _)| per_triangle[t as usize])
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    }

    /// The critical time step of the nodes against their contacts' stiffness on top of the
    /// membrane's own: `sqrt(m / (max(kn, ks) A + k_membrane))`, `A` twice the largest rest
    /// area of a node's triangles (a body pressed on all of them, stretched).
    pub fn critical_dt(&self, triangles: &[[u32; 3]]) -> f64 {
        let k = self.sheet.kn.max(self.sheet.ks) * self.contact_area();
        (self.sheet.node_mass / (k + self.node_stiffness(triangles))).sqrt()
    }

    /// Twice the largest rest area of a node's triangles, m^2: the most a contact can press.
    pub fn contact_area(&self) -> f64 {
        2.0 * (self.corners.iter())
            .map(|c| {
                c.iter()
                    .map(|&(t, _)| self.reference[t as usize].area)
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    }

    /// The walls that hold node `i` and each one's share of what it pushes on them: its
    /// pinning wall, or the guide's two walls in proportion to its rest height; none for a
    /// free node.
    fn holders(&self, i: usize) -> Vec<(usize, f64)> {
        if let Some(w) = self.pin_of(i) {
            return vec![(w as usize, 1.0)];
        }
        match (&self.guide, self.guides.get(i)) {
            (Some(g), Some(&(_, frac))) => {
                vec![(g.bottom as usize, 1.0 - frac), (g.top as usize, frac)]
            }
            _ => Vec::new(),
        }
    }

    /// The pinning wall of node `i`, if any.
    pub fn pin_of(&self, i: usize) -> Option<u32> {
        let w = self.pinned[i];
        (w != u32::MAX).then_some(w)
    }

    /// Elastic energy of the membrane with its nodes at `nodes`, J.
    pub fn elastic_energy(&self, nodes: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
        (triangles.iter().zip(&self.reference))
            .map(|(t, r)| self.triangle(t.map(|i| nodes[i as usize]), r).1)
            .sum()
    }

    /// The second Piola-Kirchhoff stress times the thickness, `(S11, S22, S12)`, of the Green
    /// strain `(E11, E22, E12)`, for a sheet that carries no compression (it wrinkles): taut,
    /// the plane-stress law `S = D E`; wrinkled (the law's minor principal stress would be
    /// negative while the major strain stretches), a uniaxial tension `t Y e1` along the major
    /// strain's direction; slack (no stretch), none. The energy `E : S / 2` is the relaxed
    /// energy of tension-field theory, continuous with its gradient across the states.
    #[inline]
    fn relaxed_stress(&self, e11: f64, e22: f64, e12: f64) -> (f64, f64, f64) {
        let (d11, d12, d33) = self.stiffness();
        let taut = (
            d11 * e11 + d12 * e22,
            d12 * e11 + d11 * e22,
            d33 * 2.0 * e12,
        );
        // Principal strains and the major direction.
        let mean = 0.5 * (e11 + e22);
        let radius = (0.25 * (e11 - e22) * (e11 - e22) + e12 * e12).sqrt();
        let (major, minor) = (mean + radius, mean - radius);
        let nu = self.sheet.poisson;
        if minor + nu * major >= 0.0 {
            return taut;
        }
        // Wrinkled or slack: the relaxed stress, with a residual share of the taut law's
        // that keeps compressed triangles from collapsing.
        let k = RESIDUAL;
        let keep = |s: (f64, f64, f64)| {
            (
                s.0 + k * (taut.0 - s.0),
                s.1 + k * (taut.1 - s.1),
                s.2 + k * (taut.2 - s.2),
            )
        };
        if major <= 0.0 {
            return keep((0.0, 0.0, 0.0));
        }
        // The major direction (c, s): an eigenvector of the strain.
        let (c, s) = if radius > 0.0 {
            let (x, y) = if e11 >= e22 {
                (major - e22, e12)
            } else {
                (e12, major - e11)
            };
            let n = (x * x + y * y).sqrt();
            (x / n, y / n)
        } else {
            (1.0, 0.0)
        };
        let tension = self.sheet.thickness * self.sheet.young * major;
        keep((tension * c * c, tension * s * s, tension * c * s))
    }

    /// A triangle's elastic forces on its corners and its elastic energy, at corners `x`.
    #[inline]
    fn triangle(&self, x: [Vec3; 3], r: &Reference) -> ([Vec3; 3], f64) {
        let (e1, e2) = (x[1] - x[0], x[2] - x[0]);
        let m = &r.dm_inv;
        // Deformation gradient F = [e1 e2] Dm^-1 (3 x 2), by columns.
        let f1 = e1 * m[0][0] + e2 * m[1][0];
        let f2 = e1 * m[0][1] + e2 * m[1][1];
        // Green-Lagrange strain E = (F^T F - I) / 2.
        let (e11, e22, e12) = (
            0.5 * (f1.dot(&f1) - 1.0),
            0.5 * (f2.dot(&f2) - 1.0),
            0.5 * f1.dot(&f2),
        );
        let (s11, s22, s12) = self.relaxed_stress(e11, e22, e12);
        let energy = 0.5 * r.area * (s11 * e11 + s22 * e22 + 2.0 * s12 * e12);
        // First Piola-Kirchhoff P = F S, by columns; forces H = -A P Dm^-T on corners b, c.
        let p1 = f1 * s11 + f2 * s12;
        let p2 = f1 * s12 + f2 * s22;
        let hb = -(p1 * m[0][0] + p2 * m[0][1]) * r.area;
        let hc = -(p1 * m[1][0] + p2 * m[1][1]) * r.area;
        ([-(hb + hc), hb, hc], energy)
    }

    /// The elastic and pressure forces on every node at `nodes`, and the elastic energy; in
    /// parallel when `par` (the same numbers either way: each node sums its triangles in
    /// triangle order).
    pub fn forces(
        &self,
        nodes: &[Vec3],
        triangles: &[[u32; 3]],
        par: bool,
    ) -> (Vec<Vec3>, Vec<Vec3>, f64) {
        let per_triangle = |(t, r): (&[u32; 3], &Reference)| {
            let x = t.map(|i| nodes[i as usize]);
            let (f, energy) = self.triangle(x, r);
            // The pressure on the triangle as it is now, a third to each corner.
            let area = (x[1] - x[0]).cross(&(x[2] - x[0])) * 0.5;
            (f, area * (self.sheet.pressure / 3.0), energy)
        };
        let items = triangles.iter().zip(&self.reference);
        let done: Vec<([Vec3; 3], Vec3, f64)> = if par {
            items
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(per_triangle)
                .collect()
        } else {
            items.map(per_triangle).collect()
        };
        let gather = |c: &Vec<(u32, u8)>| {
            let (mut el, mut pr) = (Vec3::zeros(), Vec3::zeros());
            for &(t, k) in c {
                let (f, p, _) = &done[t as usize];
                el += f[k as usize];
                pr += p;
            }
            (el, pr)
        };
        let sums: Vec<(Vec3, Vec3)> = if par {
            self.corners.par_iter().map(gather).collect()
        } else {
            self.corners.iter().map(gather).collect()
        };
        let energy = done.iter().map(|d| d.2).sum();
        let (elastic, pressure) = sums.into_iter().unzip();
        (elastic, pressure, energy)
    }
}

/// The motion a node is free to take.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Space {
    /// Any (a free node).
    All,
    /// None (sealed to its wall).
    Nothing,
    /// The plane normal to this unit vector (sliding on a platen).
    Plane(Vec3),
    /// The line along this unit vector (a guided node).
    Line(Vec3),
}

impl Space {
    /// The part of `v` in the space.
    fn project(&self, v: &Vec3) -> Vec3 {
        match self {
            Space::All => *v,
            Space::Nothing => Vec3::zeros(),
            Space::Plane(n) => v - n * n.dot(v),
            Space::Line(d) => d * d.dot(v),
        }
    }

    /// PFC's local damping of force `f` against the free velocity `v`: per world component for
    /// a free node, along the line for a guided one.
    fn damping(&self, f: &Vec3, v: &Vec3, alpha: f64) -> Vec3 {
        match self {
            Space::Line(d) => {
                let vd = d.dot(v);
                if vd == 0.0 {
                    Vec3::zeros()
                } else {
                    d * (-alpha * d.dot(f).abs() * vd.signum())
                }
            }
            _ => Vec3::from_fn(|j, _| {
                if v[j] == 0.0 {
                    0.0
                } else {
                    -alpha * f[j].abs() * v[j].signum()
                }
            }),
        }
    }
}

/// Node `i`'s free space and the velocity imposed on the rest of its motion, from the walls'
/// velocities now.
fn constraint(m: &Membrane, walls: &[Wall], i: usize) -> (Space, Vec3) {
    if let Some(w) = m.pin_of(i) {
        let wall = &walls[w as usize];
        return match (&wall.kind, m.sealed) {
            (WallKind::Plane { normal, .. }, false) => {
                (Space::Plane(*normal), normal * normal.dot(&wall.velocity))
            }
            _ => (Space::Nothing, wall.velocity),
        };
    }
    match (&m.guide, m.guides.get(i)) {
        (Some(g), Some(&(dir, frac))) => {
            let (vb, vt) = (
                walls[g.bottom as usize].velocity,
                walls[g.top as usize].velocity,
            );
            (Space::Line(dir), vb + (vt - vb) * frac)
        }
        _ => (Space::All, Vec3::zeros()),
    }
}

/// The kinetic energy of the free motion of the membrane of a facet wall with these node
/// velocities, the walls as they are.
pub fn kinetic_energy(m: &Membrane, node_velocities: &[Vec3], walls: &[Wall]) -> f64 {
    (node_velocities.iter().enumerate())
        .map(|(i, v)| 0.5 * m.sheet.node_mass * constraint(m, walls, i).0.project(v).norm_squared())
        .sum()
}

/// Sets the velocity of every held node (pinned or guided) of the membranes among `walls` from
/// its walls', as the step is about to move them: each keeps its free part and takes the
/// imposed one.
pub fn pin_velocities(walls: &mut [Wall]) {
    for k in 0..walls.len() {
        let Some(m) = walls[k].membrane.take() else {
            continue;
        };
        let n = match &walls[k].kind {
            WallKind::Facets { nodes, .. } => nodes.len(),
            _ => 0,
        };
        let held: Vec<(usize, Space, Vec3)> = (0..n)
            .filter(|&i| m.pin_of(i).is_some() || m.guide.is_some())
            .map(|i| {
                let (space, imposed) = constraint(&m, walls, i);
                (i, space, imposed)
            })
            .collect();
        if let WallKind::Facets {
            node_velocities, ..
        } = &mut walls[k].kind
        {
            for (i, space, imposed) in held {
                let v = &mut node_velocities[i];
                *v = space.project(v) + imposed;
            }
        }
        walls[k].membrane = Some(m);
    }
}

/// Moves the nodes of wall `k`'s membrane on by one step `dt` after this step's contacts (its
/// `node_forces`): elastic and pressure forces at the nodes as they are, local damping
/// (the sheet's, or else `alpha`), and the kick to the velocities of the next step. Returns the energy terms.
pub fn kick(walls: &mut [Wall], k: usize, dt: f64, alpha: f64, par: bool) -> MembraneEnergy {
    let Some(m) = walls[k].membrane.take() else {
        return MembraneEnergy::default();
    };
    let alpha = m.sheet.damping.unwrap_or(alpha);
    let mut out = MembraneEnergy::default();
    let n = match &walls[k].kind {
        WallKind::Facets { nodes, .. } => nodes.len(),
        _ => 0,
    };
    let constraints: Vec<(Space, Vec3)> = (0..n).map(|i| constraint(&m, walls, i)).collect();
    // What the held nodes push on their walls (the part of their force the constraint takes),
    // by wall: a sealed end carries the membrane's axial load to its platen, as in the test.
    let mut reactions = vec![Vec3::zeros(); walls.len()];
    if let WallKind::Facets {
        nodes,
        triangles,
        node_velocities,
        node_forces,
    } = &mut walls[k].kind
    {
        let (elastic, pressure, energy) = m.forces(nodes, triangles, par);
        out.elastic = energy;
        for (i, (space, imposed)) in constraints.iter().enumerate() {
            let free_old = space.project(&node_velocities[i]);
            let internal = elastic[i] + node_forces[i];
            // The force on the free motion, damped as a body's is.
            let total = internal + pressure[i];
            let free_force = space.project(&total);
            let held = total - free_force;
            if held != Vec3::zeros() {
                for (w, share) in m.holders(i) {
                    reactions[w] += held * share;
                }
            }
            let damp = space.damping(&free_force, &free_old, alpha);
            let free_new = free_old + (free_force + damp) * (dt / m.sheet.node_mass);
            let mean = (free_old + free_new) * 0.5;
            out.pressure_work += pressure[i].dot(&mean) * dt;
            out.damping -= damp.dot(&mean) * dt;
            out.kinetic += 0.5 * m.sheet.node_mass * free_new.norm_squared();
            // The holding walls keep the node on its path against everything but the pressure
            // (which acts on them through it).
            out.wall_work -= internal.dot(imposed) * dt;
            node_velocities[i] = free_new + imposed;
        }
    }
    walls[k].membrane = Some(m);
    for (wall, r) in walls.iter_mut().zip(reactions) {
        wall.force += r;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sheet(young: f64, poisson: f64, thickness: f64, pressure: f64) -> Sheet {
        Sheet {
            young,
            poisson,
            thickness,
            pressure,
            node_mass: 1.0,
            kn: 1e6,
            ks: 5e5,
            damping: None,
            reach: 1.0,
        }
    }

    fn patch() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        // Two triangles of a unit square in the plane z = 0.3, seen from +z.
        let nodes = vec![
            Vec3::new(0.0, 0.0, 0.3),
            Vec3::new(1.0, 0.0, 0.3),
            Vec3::new(1.0, 1.0, 0.3),
            Vec3::new(0.0, 1.0, 0.3),
        ];
        (nodes, vec![[0, 1, 2], [0, 2, 3]])
    }

    /// A uniform stretch of a patch of constant-strain triangles gives the exact plane stress
    /// of St Venant-Kirchhoff: stretches `l1`, `l2` along x and y, Green strains
    /// `E_i = (l_i^2 - 1) / 2`, `S = D E`, and the force on the patch's x edge is the first
    /// Piola-Kirchhoff traction `l1 S11` times the edge's rest length and the thickness; the
    /// energy is the density times the rest area. A rigid rotation on top changes neither.
    #[test]
    fn a_uniform_stretch_of_a_cst_patch_gives_the_exact_stress() {
        let (rest, triangles) = patch();
        let (young, nu, t) = (7.8e6, 0.5, 2e-3);
        let m = Membrane::new(
            sheet(young, nu, t, 0.0),
            rest.clone(),
            &triangles,
            vec![],
            true,
            None,
            0,
        )
        .unwrap();
        let (l1, l2) = (1.1, 0.97);
        let turn = nalgebra::UnitQuaternion::from_scaled_axis(Vec3::new(0.3, -0.2, 0.5));
        let x: Vec<Vec3> = (rest.iter())
            .map(|p| turn * Vec3::new(p.x * l1, p.y * l2, 0.0) + Vec3::new(2.0, 1.0, -1.0))
            .collect();
        let (f, _, energy) = m.forces(&x, &triangles, false);
        let (e1, e2) = (0.5 * (l1 * l1 - 1.0), 0.5 * (l2 * l2 - 1.0));
        let d = young / (1.0 - nu * nu);
        let (s1, s2) = (d * (e1 + nu * e2), d * (nu * e1 + e2));
        // The nodes at x = 1 (1 and 2) are pulled back by the traction l1 S11 t over the unit
        // rest edge, along the stretched x axis; the forces balance.
        let edge = f[1] + f[2];
        let expected = turn * Vec3::new(-l1 * s1 * t, 0.0, 0.0);
        assert!(
            (edge - expected).norm() < 1e-9 * expected.norm(),
            "{edge:?} {expected:?}"
        );
        let top = f[2] + f[3];
        let expected = turn * Vec3::new(0.0, -l2 * s2 * t, 0.0);
        assert!(
            (top - expected).norm() < 1e-9 * expected.norm(),
            "{top:?} {expected:?}"
        );
        assert!(f.iter().sum::<Vec3>().norm() < 1e-9 * expected.norm());
        let density = 0.5 * t * (s1 * e1 + s2 * e2);
        assert!(
            (energy - density).abs() < 1e-12 * density,
            "{energy} {density}"
        );
        // At rest, rotated and moved: no force, no energy.
        let moved: Vec<Vec3> = rest
            .iter()
            .map(|p| turn * p + Vec3::new(0.1, 0.2, 0.3))
            .collect();
        let (f, _, energy) = m.forces(&moved, &triangles, false);
        assert!(f.iter().all(|f| f.norm() < 1e-9), "{f:?}");
        assert!(energy.abs() < 1e-18);
    }

    /// A sheet carries no compression but its residual share: stretched along x and squeezed
    /// along y past the plane-stress law's zero (`E22 < -nu E11`) it carries the uniaxial
    /// tension `t Y E11` along x (plus `RESIDUAL` of the taut law's difference); squeezed both
    /// ways, only the residual share.
    #[test]
    fn a_wrinkled_sheet_carries_uniaxial_tension_and_a_slack_one_next_to_nothing() {
        let (rest, triangles) = patch();
        let (young, nu, t) = (7.8e6, 0.5, 2e-3);
        let m = Membrane::new(
            sheet(young, nu, t, 0.0),
            rest.clone(),
            &triangles,
            vec![],
            true,
            None,
            0,
        )
        .unwrap();
        let stretched = |l1: f64, l2: f64| -> Vec<Vec3> {
            rest.iter()
                .map(|p| Vec3::new(p.x * l1, p.y * l2, 0.3))
                .collect()
        };
        let taut = |e1: f64, e2: f64| {
            let d = t * young / (1.0 - nu * nu);
            (d * (e1 + nu * e2), d * (nu * e1 + e2))
        };
        let k = RESIDUAL;
        for (l1, l2) in [(1.05, 0.9), (0.95, 0.9)] {
            let (e1, e2) = (0.5 * (l1 * l1 - 1.0), 0.5 * (l2 * l2 - 1.0));
            let (t1, t2) = taut(e1, e2);
            let relaxed = if e1 > 0.0 { young * t * e1 } else { 0.0 };
            let (s1, s2) = (relaxed + k * (t1 - relaxed), k * t2);
            let (f, _, energy) = m.forces(&stretched(l1, l2), &triangles, false);
            let edge = f[1] + f[2];
            let expected = Vec3::new(-l1 * s1, 0.0, 0.0);
            assert!(
                (edge - expected).norm() < 1e-9 * expected.norm(),
                "{edge:?} {expected:?}"
            );
            let top = f[2] + f[3];
            assert!((top.y + l2 * s2).abs() < 1e-9 * expected.norm(), "{top:?}");
            let want = 0.5 * (s1 * e1 + s2 * e2);
            assert!(
                (energy - want).abs() < 1e-12 * want.abs(),
                "{energy} {want}"
            );
            // Turned in its plane, the same energy.
            let turn = nalgebra::UnitQuaternion::from_axis_angle(&Vec3::z_axis(), 0.5);
            let x: Vec<Vec3> = stretched(l1, l2).iter().map(|p| turn * p).collect();
            let (_, _, e) = m.forces(&x, &triangles, false);
            assert!((e - energy).abs() < 1e-9 * energy.abs());
        }
    }

    /// The elastic forces are minus the gradient of the elastic energy (central differences),
    /// and the pressure is `p` times each triangle's area vector, a third to each corner.
    #[test]
    fn elastic_forces_are_the_energy_gradient_and_pressure_follows_the_facets() {
        let (rest, triangles) = patch();
        let m = Membrane::new(
            sheet(7.8e6, 0.45, 2e-3, 1e5),
            rest.clone(),
            &triangles,
            vec![],
            true,
            None,
            0,
        )
        .unwrap();
        let x: Vec<Vec3> = vec![
            Vec3::new(0.02, -0.01, 0.3),
            Vec3::new(1.05, 0.03, 0.32),
            Vec3::new(0.98, 1.1, 0.25),
            Vec3::new(-0.04, 0.95, 0.31),
        ];
        let (f, p, _) = m.forces(&x, &triangles, false);
        let h = 1e-7;
        for i in 0..4 {
            for j in 0..3 {
                let mut a = x.clone();
                let mut b = x.clone();
                a[i][j] += h;
                b[i][j] -= h;
                let grad = (m.elastic_energy(&a, &triangles) - m.elastic_energy(&b, &triangles))
                    / (2.0 * h);
                assert!(
                    (f[i][j] + grad).abs() < 1e-4 * (1.0 + grad.abs()),
                    "{i} {j}"
                );
            }
        }
        let area = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|i| x[i as usize]);
            (b - a).cross(&(c - a)) * 0.5
        };
        let expected = (area(&triangles[0]) + area(&triangles[1])) * (1e5 / 3.0);
        assert!((p[0] - expected).norm() < 1e-9 * expected.norm());
        // The same numbers in parallel.
        assert_eq!(
            m.forces(&x, &triangles, true),
            m.forces(&x, &triangles, false)
        );
    }

    #[test]
    fn nonsense_parameters_and_pins_are_refused() {
        let (rest, triangles) = patch();
        let make = |young: f64, nu: f64, pins: Vec<Pin>| {
            Membrane::new(
                sheet(young, nu, 2e-3, 1e5),
                rest.clone(),
                &triangles,
                pins,
                true,
                None,
                2,
            )
        };
        assert!(matches!(
            make(-1.0, 0.3, vec![]),
            Err(MembraneError::Param { field: "young", .. })
        ));
        assert!(matches!(
            make(1e6, 0.6, vec![]),
            Err(MembraneError::Param {
                field: "poisson",
                ..
            })
        ));
        assert!(make(1e6, 0.3, vec![Pin { node: 9, wall: 0 }]).is_err());
        assert!(make(1e6, 0.3, vec![Pin { node: 1, wall: 2 }]).is_err());
        let twice = vec![Pin { node: 1, wall: 0 }, Pin { node: 1, wall: 1 }];
        assert!(make(1e6, 0.3, twice).is_err());
        let mut flat = rest.clone();
        flat[2] = flat[0];
        assert!(matches!(
            Membrane::new(
                sheet(1e6, 0.3, 2e-3, 0.0),
                flat,
                &triangles,
                vec![],
                true,
                None,
                0
            ),
            Err(MembraneError::Flat(0))
        ));
    }
}
