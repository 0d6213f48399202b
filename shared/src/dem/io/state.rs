//! Scenes and states as JSON lines (format `granular-dem`, version 1, SI units).
//!
//! One record per line, a header first. A *state* (what `dem` writes) is a complete restart
//! point: shapes in their principal frame with the derived quantities the engine uses, bodies
//! (velocities at the half step, as the leapfrog keeps them), walls, contacts with their shear
//! springs, time, step and the energy accumulators; floats are written as the shortest text that
//! reads back to the same f64, so a run restarted from a state continues bit for bit. A *scene*
//! (what a user writes) may give shapes as plain meshes (`vertices` and `faces`, any frame) and
//! leave out what follows from them. The records are specified with examples in
//! `docs/formats/dem-state.md`.

use crate::dem::contacts::Partner;
use crate::dem::energy::Energy;
use crate::dem::law::{Contact, Material};
use crate::dem::membrane::{Guide, Membrane, Pin, Sheet};
use crate::dem::shape::{Shape, ShapeError};
use crate::dem::wall::{Wall, WallKind};
use crate::dem::world::{Body, World};
use crate::geometry::mesh::PolyMesh;
use crate::math::Vec3;
use nalgebra::{Quaternion, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::io::{BufRead, Write};
use thiserror::Error;

/// The format name in the header.
pub const FORMAT: &str = "granular-dem";
/// The version this code reads and writes.
pub const VERSION: u32 = 1;

/// A scene or state error, naming the line.
#[derive(Debug, Error)]
pub enum StateError {
    #[error("reading the scene: {0}")]
    Io(#[from] std::io::Error),
    #[error("line {line}: {msg}")]
    Line { line: usize, msg: String },
    #[error("{0}")]
    Scene(String),
}

fn at(line: usize, msg: impl Into<String>) -> StateError {
    StateError::Line {
        line,
        msg: msg.into(),
    }
}

/// One JSON line.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Record {
    Header {
        format: String,
        version: u32,
        units: String,
    },
    Material(Material),
    Clock {
        time: f64,
        step: u64,
        dt: f64,
        gravity: [f64; 3],
    },
    Shape(ShapeRecord),
    Body(BodyRecord),
    Wall(WallRecord),
    Contact(ContactRecord),
    Energy {
        friction: f64,
        damping: f64,
        gravity_work: f64,
        wall_work: f64,
        /// Taken by the membranes' damping (absent without membranes).
        #[serde(default, skip_serializing_if = "is_zero")]
        membrane_damping: f64,
        /// Work of the membranes' pressure (absent without membranes).
        #[serde(default, skip_serializing_if = "is_zero")]
        pressure_work: f64,
    },
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

/// A shape: either a mesh (`vertices`, `faces`; its convex hull is taken and moved to the
/// principal frame) or, as `dem` writes it, the principal form with its derived quantities.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShapeRecord {
    pub id: u32,
    pub name: String,
    pub vertices: Vec<[f64; 3]>,
    pub faces: Vec<Vec<u32>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub principal: Option<Principal>,
}

/// What the engine derives from a shape, stored so that a restart needs no recomputation.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Principal {
    pub normals: Vec<[f64; 3]>,
    pub offsets: Vec<f64>,
    pub volume: f64,
    pub moments: [f64; 3],
    pub radius: f64,
    pub centroid_in_mesh: [f64; 3],
    pub frame_in_mesh: [f64; 4],
}

/// A body. `rot` is the unit quaternion (w, x, y, z) from the shape's principal frame to world
/// axes; `vel` and `ang_mom` (world axes, about the centroid) are at the half step.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyRecord {
    pub id: u32,
    pub shape: u32,
    pub scale: f64,
    pub pos: [f64; 3],
    #[serde(default = "identity")]
    pub rot: [f64; 4],
    #[serde(default)]
    pub vel: [f64; 3],
    #[serde(default)]
    pub ang_mom: [f64; 3],
    #[serde(default)]
    pub fixed: bool,
    /// The body's mass and principal moments when they are not those of its shape at the
    /// material's density (scaled inertia, for a quasi-static procedure), kg and kg m^2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub moments: Option<[f64; 3]>,
}

fn identity() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// A wall. `kind` "plane": `normal` (unit), `offset` (solid where normal . x <= offset);
/// "facets": `nodes`, `triangles` (counter-clockwise seen from the particles' side), optional
/// `node_velocities` (and `node_forces`, written by `dem`); "cylinder": `point`, `axis` (unit),
/// `radius`, `height`, `segments` (flat facets inscribed in the circle), optional `radial_rate`.
/// Every kind: optional `velocity` (a rigid motion) and `force` (written by `dem`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallRecord {
    pub id: u32,
    pub kind: String,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nodes: Option<Vec<[f64; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub triangles: Option<Vec<[u32; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node_velocities: Option<Vec<[f64; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node_forces: Option<Vec<[f64; 3]>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub segments: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radial_rate: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub membrane: Option<MembraneRecord>,
    #[serde(default)]
    pub velocity: [f64; 3],
    #[serde(default)]
    pub force: [f64; 3],
}

/// A facet wall's membrane ([`Membrane`]): its material (`young` Pa, `poisson`, `thickness` m),
/// the `pressure` on its outer side (Pa), the mass of each node (kg), the stiffness of the
/// particles' contacts with it (`kn`, N/m^3, a Winkler foundation's; `ks` likewise, which
/// no law reads while the contacts are frictionless, as reading demands), its pinned nodes
/// (`[node, wall]`) and whether they are `sealed` to their walls or slide on them, and the
/// nodes' `rest` positions (the unstressed membrane).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MembraneRecord {
    pub young: f64,
    pub poisson: f64,
    pub thickness: f64,
    pub pressure: f64,
    pub node_mass: f64,
    pub kn: f64,
    pub ks: f64,
    /// The nodes' local damping, when not the material's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<f64>,
    pub reach: f64,
    pub sealed: bool,
    pub pins: Vec<[u32; 2]>,
    /// The walls that guide the nodes not pinned (`[bottom, top]`), if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub guide: Option<[u32; 2]>,
    pub rest: Vec<[f64; 3]>,
}

impl MembraneRecord {
    fn of(m: &Membrane) -> MembraneRecord {
        let s = &m.sheet;
        MembraneRecord {
            young: s.young,
            poisson: s.poisson,
            thickness: s.thickness,
            pressure: s.pressure,
            node_mass: s.node_mass,
            kn: s.kn,
            ks: s.ks,
            damping: s.damping,
            reach: s.reach,
            sealed: m.sealed,
            pins: m.pins.iter().map(|p| [p.node, p.wall]).collect(),
            guide: m.guide.map(|g| [g.bottom, g.top]),
            rest: m.rest.iter().map(a3).collect(),
        }
    }

    /// The membrane of a facet wall of `nodes` and `triangles`; the pins' walls are checked
    /// once every wall is read.
    fn to_membrane(&self, nodes: usize, triangles: &[[u32; 3]]) -> Result<Membrane, String> {
        all_finite("membrane rest", self.rest.iter().flatten())?;
        if self.rest.len() != nodes {
            return Err(format!(
                "membrane rest has {} entries for {nodes} nodes",
                self.rest.len()
            ));
        }
        let pins = (self.pins.iter())
            .map(|&[node, wall]| Pin { node, wall })
            .collect();
        let rest = self.rest.iter().map(v3).collect();
        let sheet = Sheet {
            young: self.young,
            poisson: self.poisson,
            thickness: self.thickness,
            pressure: self.pressure,
            node_mass: self.node_mass,
            kn: self.kn,
            ks: self.ks,
            damping: self.damping,
            reach: self.reach,
        };
        Membrane::new(
            sheet,
            rest,
            triangles,
            pins,
            self.sealed,
            self.guide.map(|[bottom, top]| Guide { bottom, top }),
            usize::MAX,
        )
        .map_err(|e| format!("membrane: {e}"))
    }
}

impl WallRecord {
    fn from_wall(id: u32, w: &Wall) -> WallRecord {
        let mut r = WallRecord {
            id,
            velocity: a3(&w.velocity),
            force: a3(&w.force),
            ..Default::default()
        };
        match &w.kind {
            WallKind::Plane { normal, offset } => {
                r.kind = "plane".into();
                r.normal = Some(a3(normal));
                r.offset = Some(*offset);
            }
            WallKind::Facets {
                nodes,
                triangles,
                node_velocities,
                node_forces,
            } => {
                r.kind = "facets".into();
                r.nodes = Some(nodes.iter().map(a3).collect());
                r.triangles = Some(triangles.clone());
                r.node_velocities = Some(node_velocities.iter().map(a3).collect());
                r.node_forces = Some(node_forces.iter().map(a3).collect());
                r.membrane = w.membrane.as_deref().map(MembraneRecord::of);
            }
            WallKind::Cylinder {
                point,
                axis,
                radius,
                height,
                segments,
                radial_rate,
            } => {
                r.kind = "cylinder".into();
                r.point = Some(a3(point));
                r.axis = Some(a3(axis));
                r.radius = Some(*radius);
                r.height = Some(*height);
                r.segments = Some(*segments);
                r.radial_rate = Some(*radial_rate);
            }
        }
        r
    }

    /// The wall, or what is wrong with the record.
    fn to_wall(&self) -> Result<Wall, String> {
        fn need<T: Clone>(v: &Option<T>, kind: &str, field: &str) -> Result<T, String> {
            v.clone()
                .ok_or_else(|| format!("a {kind} wall needs '{field}'"))
        }
        fn unit(v: &[f64; 3], what: &str) -> Result<Vec3, String> {
            let n = v3(v).norm();
            if (n - 1.0).abs() > 1e-9 {
                return Err(format!("wall {what} has length {n}, not 1"));
            }
            Ok(v3(v))
        }
        all_finite("velocity", &self.velocity)?;
        let kind = self.kind.as_str();
        let others: Vec<&str> = [
            ("normal", self.normal.is_some()),
            ("offset", self.offset.is_some()),
            ("nodes", self.nodes.is_some()),
            ("triangles", self.triangles.is_some()),
            ("node_velocities", self.node_velocities.is_some()),
            ("node_forces", self.node_forces.is_some()),
            ("point", self.point.is_some()),
            ("axis", self.axis.is_some()),
            ("radius", self.radius.is_some()),
            ("height", self.height.is_some()),
            ("segments", self.segments.is_some()),
            ("radial_rate", self.radial_rate.is_some()),
            ("membrane", self.membrane.is_some()),
        ]
        .into_iter()
        .filter(|(_, set)| *set)
        .map(|(name, _)| name)
        .collect();
        let allowed: &[&str] = match kind {
            "plane" => &["normal", "offset"],
            "facets" => &[
                "nodes",
                "triangles",
                "node_velocities",
                "node_forces",
                "membrane",
            ],
            "cylinder" => &[
                "point",
                "axis",
                "radius",
                "height",
                "segments",
                "radial_rate",
            ],
            _ => {
                return Err(format!(
                    "wall kind '{kind}' is not known (plane, facets, cylinder)"
                ))
            }
        };
        if let Some(f) = others.iter().find(|f| !allowed.contains(f)) {
            return Err(format!("a {kind} wall has no field '{f}'"));
        }
        let wall_kind = match kind {
            "plane" => {
                let normal = need(&self.normal, kind, "normal")?;
                let offset = need(&self.offset, kind, "offset")?;
                all_finite("normal", normal.iter().chain([&offset]))?;
                WallKind::Plane {
                    normal: unit(&normal, "normal")?,
                    offset,
                }
            }
            "facets" => {
                let nodes = need(&self.nodes, kind, "nodes")?;
                let triangles = need(&self.triangles, kind, "triangles")?;
                if triangles.is_empty() {
                    return Err("a facets wall needs at least one triangle".into());
                }
                all_finite("node", nodes.iter().flatten())?;
                let nodes: Vec<Vec3> = nodes.iter().map(v3).collect();
                for (k, t) in triangles.iter().enumerate() {
                    if let Some(i) = t.iter().find(|&&i| i as usize >= nodes.len()) {
                        return Err(format!(
                            "triangle {k} uses node {i}, but there are {} nodes",
                            nodes.len()
                        ));
                    }
                    let [a, b, c] = t.map(|i| nodes[i as usize]);
                    let area = (b - a).cross(&(c - a)).norm();
                    if area.is_nan()
                        || area <= 1e-12 * (b - a).norm_squared().max((c - a).norm_squared())
                    {
                        return Err(format!("triangle {k} has no area"));
                    }
                }
                let per_node = |v: &Option<Vec<[f64; 3]>>, what: &str| match v {
                    None => Ok(vec![Vec3::zeros(); nodes.len()]),
                    Some(v) if v.len() == nodes.len() => {
                        all_finite(what, v.iter().flatten())?;
                        Ok(v.iter().map(v3).collect())
                    }
                    Some(v) => Err(format!(
                        "{what} has {} entries for {} nodes",
                        v.len(),
                        nodes.len()
                    )),
                };
                WallKind::Facets {
                    node_velocities: per_node(&self.node_velocities, "node_velocities")?,
                    node_forces: per_node(&self.node_forces, "node_forces")?,
                    nodes,
                    triangles,
                }
            }
            _ => {
                let point = need(&self.point, kind, "point")?;
                let axis = need(&self.axis, kind, "axis")?;
                let radius = need(&self.radius, kind, "radius")?;
                let height = need(&self.height, kind, "height")?;
                let segments = need(&self.segments, kind, "segments")?;
                let radial_rate = self.radial_rate.unwrap_or(0.0);
                all_finite(
                    "cylinder",
                    point
                        .iter()
                        .chain(&axis)
                        .chain([&radius, &height, &radial_rate]),
                )?;
                if radius <= 0.0 || height <= 0.0 {
                    return Err(format!(
                        "a cylinder needs a positive radius and height (got {radius}, {height})"
                    ));
                }
                if segments < 3 {
                    return Err(format!(
                        "a cylinder needs at least 3 segments (got {segments})"
                    ));
                }
                WallKind::Cylinder {
                    point: v3(&point),
                    axis: unit(&axis, "axis")?,
                    radius,
                    height,
                    segments,
                    radial_rate,
                }
            }
        };
        let membrane = match (&self.membrane, &wall_kind) {
            (
                Some(m),
                WallKind::Facets {
                    nodes, triangles, ..
                },
            ) => Some(Box::new(m.to_membrane(nodes.len(), triangles)?)),
            _ => None,
        };
        Ok(Wall {
            kind: wall_kind,
            velocity: v3(&self.velocity),
            force: v3(&self.force),
            membrane,
        })
    }
}

/// A contact: body `body` touched by `partner` (`{"body": i}` or `{"wall": j}`); the normal
/// points from the partner to the body; forces act on the body (the partner gets the opposite).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactRecord {
    pub body: u32,
    pub partner: PartnerRecord,
    pub normal: [f64; 3],
    pub point: [f64; 3],
    pub depth: f64,
    pub normal_force: f64,
    /// Energy stored by the normal force, J (see `Contact::potential`); when absent,
    /// `normal_force^2 / 2kn` (exact for faces pressed flat).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub potential: Option<f64>,
    pub shear: [f64; 3],
    pub sliding: bool,
}

#[derive(Clone, Copy, Debug, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
pub enum PartnerRecord {
    Body(u32),
    Wall(u32),
}

fn v3(a: &[f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

fn a3(v: &Vec3) -> [f64; 3] {
    [v.x, v.y, v.z]
}

fn finite(line: usize, what: &str, xs: &[f64]) -> Result<(), StateError> {
    if xs.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(at(line, format!("{what} has a value that is not finite")))
    }
}

/// Reads a scene or state. Shapes given as meshes must be closed, outward and convex.
pub fn read_world<R: BufRead>(input: R) -> Result<World, StateError> {
    let mut world = World::new(Material::default(), Vec3::zeros());
    let mut header = false;
    let mut material_seen = false;
    let (mut clock_seen, mut energy_seen) = (false, false);
    let mut energy = Energy::default();
    let mut pending_bodies: Vec<(usize, BodyRecord)> = Vec::new();
    let mut contacts = Vec::new();
    let mut last_line = 0;
    for (k, line) in input.lines().enumerate() {
        let n = k + 1;
        last_line = n;
        let line = line?;
        if line.trim().is_empty() {
            continue;
        }
        let rec: Record = serde_json::from_str(&line).map_err(|e| at(n, e.to_string()))?;
        if !header {
            match &rec {
                Record::Header {
                    format,
                    version,
                    units,
                } => {
                    if format != FORMAT {
                        return Err(at(n, format!("format '{format}' is not '{FORMAT}'")));
                    }
                    if *version != VERSION {
                        return Err(at(n, format!("version {version} is not supported (this dem reads version {VERSION})")));
                    }
                    if units != "SI" {
                        return Err(at(n, format!("units '{units}' are not 'SI'")));
                    }
                    header = true;
                    continue;
                }
                _ => {
                    return Err(at(
                        n,
                        "the first record must be the header {\"type\":\"header\",...}",
                    ))
                }
            }
        }
        match rec {
            Record::Header { .. } => return Err(at(n, "a second header")),
            Record::Material(m) => {
                if material_seen {
                    return Err(at(n, "a second material record"));
                }
                m.check().map_err(|e| at(n, format!("material: {e}")))?;
                world.material = m;
                material_seen = true;
            }
            Record::Clock {
                time,
                step,
                dt,
                gravity,
            } => {
                if clock_seen {
                    return Err(at(n, "a second clock record"));
                }
                clock_seen = true;
                finite(n, "clock", &[time, dt, gravity[0], gravity[1], gravity[2]])?;
                if time < 0.0 {
                    return Err(at(n, "the clock's time must not be negative"));
                }
                if dt < 0.0 {
                    return Err(at(n, "dt must not be negative (0: choose automatically)"));
                }
                world.time = time;
                world.step = step;
                world.dt = dt;
                world.gravity = v3(&gravity);
            }
            Record::Shape(s) => {
                in_order(n, "shape", s.id, world.shapes.len())?;
                world.shapes.push(shape_from_record(n, s)?);
            }
            Record::Body(b) => {
                in_order(n, "body", b.id, pending_bodies.len())?;
                pending_bodies.push((n, b));
            }
            Record::Wall(w) => {
                in_order(n, "wall", w.id, world.walls.len())?;
                world.walls.push(w.to_wall().map_err(|e| at(n, e))?);
            }
            Record::Contact(c) => contacts.push((n, c)),
            Record::Energy {
                friction,
                damping,
                gravity_work,
                wall_work,
                membrane_damping,
                pressure_work,
            } => {
                if energy_seen {
                    return Err(at(n, "a second energy record"));
                }
                energy_seen = true;
                finite(
                    n,
                    "energy",
                    &[
                        friction,
                        damping,
                        gravity_work,
                        wall_work,
                        membrane_damping,
                        pressure_work,
                    ],
                )?;
                energy = Energy {
                    friction,
                    damping,
                    gravity_work,
                    wall_work,
                    membrane_damping,
                    pressure_work,
                    ..Default::default()
                };
            }
        }
    }
    if !header {
        return Err(StateError::Scene(
            "the input is empty: expected a scene starting with a header line".into(),
        ));
    }
    if !material_seen {
        return Err(at(last_line, "no material record"));
    }
    for (n, b) in pending_bodies {
        world.shapes.get(b.shape as usize).ok_or_else(|| {
            at(
                n,
                format!(
                    "body {} uses shape {} which is not defined (before it)",
                    b.id, b.shape
                ),
            )
        })?;
        finite(
            n,
            "body",
            &[
                b.scale,
                b.pos[0],
                b.pos[1],
                b.pos[2],
                b.rot[0],
                b.rot[1],
                b.rot[2],
                b.rot[3],
                b.vel[0],
                b.vel[1],
                b.vel[2],
                b.ang_mom[0],
                b.ang_mom[1],
                b.ang_mom[2],
            ],
        )?;
        if b.scale <= 0.0 {
            return Err(at(
                n,
                format!(
                    "body {} has scale {}: it must be positive (zero mass otherwise)",
                    b.id, b.scale
                ),
            ));
        }
        let q = Quaternion::new(b.rot[0], b.rot[1], b.rot[2], b.rot[3]);
        if (q.norm() - 1.0).abs() > 1e-9 {
            return Err(at(
                n,
                format!("body {} orientation has norm {}, not 1", b.id, q.norm()),
            ));
        }
        let i = world.add_body(
            b.shape,
            b.scale,
            v3(&b.pos),
            UnitQuaternion::new_unchecked(q),
        );
        let body = &mut world.bodies[i];
        body.vel = v3(&b.vel);
        body.ang_mom = v3(&b.ang_mom);
        body.fixed = b.fixed;
        match (b.mass, b.moments) {
            (None, None) => {}
            (Some(mass), Some(moments)) => {
                if !(mass > 0.0
                    && mass.is_finite()
                    && moments.iter().all(|m| *m > 0.0 && m.is_finite()))
                {
                    return Err(at(
                        n,
                        format!(
                            "body {}: mass and moments must be positive and finite",
                            b.id
                        ),
                    ));
                }
                body.mass = mass;
                body.moments = v3(&moments);
            }
            _ => {
                return Err(at(
                    n,
                    format!("body {}: give both mass and moments, or neither", b.id),
                ))
            }
        }
    }
    for (n, c) in contacts {
        let nb = world.bodies.len() as u32;
        let partner = match c.partner {
            PartnerRecord::Body(a) if a < c.body => Partner::Body(a),
            PartnerRecord::Wall(w) if (w as usize) < world.walls.len() => Partner::Wall(w),
            _ => {
                return Err(at(
                    n,
                    "contact partner is not a known wall or a body with a lower id",
                ))
            }
        };
        if c.body >= nb {
            return Err(at(
                n,
                format!("contact names body {} which does not exist", c.body),
            ));
        }
        finite(
            n,
            "contact",
            &[
                c.normal[0],
                c.normal[1],
                c.normal[2],
                c.point[0],
                c.point[1],
                c.point[2],
                c.depth,
                c.normal_force,
                c.shear[0],
                c.shear[1],
                c.shear[2],
                c.potential.unwrap_or(0.0),
            ],
        )?;
        if (v3(&c.normal).norm() - 1.0).abs() > 1e-6 {
            return Err(at(n, "the contact's normal is not a unit vector"));
        }
        let old = world.contacts.insert(
            (partner, c.body),
            Contact {
                normal: v3(&c.normal),
                point: v3(&c.point),
                depth: c.depth,
                normal_force: c.normal_force,
                potential: c
                    .potential
                    .unwrap_or(0.5 * crate::math::square(c.normal_force) / world.material.kn),
                shear: v3(&c.shear),
                sliding: c.sliding,
            },
        );
        if old.is_some() {
            return Err(at(n, "a second contact of the same pair"));
        }
    }
    world.energy = Energy {
        kinetic: world.bodies.iter().map(Body::kinetic_energy).sum(),
        ..energy
    };
    world.energy.elastic = world
        .contacts
        .values()
        .map(|c| c.elastic_energy(&world.material))
        .sum();
    check_membranes(&mut world)?;
    check_fixed_overlaps(&world)?;
    Ok(world)
}

/// The number of records (lines) [`write_world`] writes for `world`.
pub fn record_count(world: &World) -> usize {
    // Header, material, clock, shapes, bodies, walls, contacts, energy.
    3 + world.shapes.len() + world.bodies.len() + world.walls.len() + world.contacts.len() + 1
}

/// The record types of a state (besides its header).
const STATE_RECORDS: [&str; 7] = [
    "material", "clock", "shape", "body", "wall", "contact", "energy",
];

/// The `type` of a JSON-lines record: read off the line's start when it is written as the
/// tools write it (`{"type":"...`), else from the parsed line; `None` when it has none.
pub fn record_type(line: &str) -> Option<String> {
    let line = line.trim_start_matches('\u{feff}').trim_start();
    if let Some(rest) = line.strip_prefix("{\"type\":\"") {
        if let Some(end) = rest.find('"') {
            return Some(rest[..end].to_string());
        }
    }
    let v: serde_json::Value = serde_json::from_str(line).ok()?;
    v.get("type")?.as_str().map(str::to_string)
}

/// An item of a stream of states ([`StateStream`]).
#[derive(Debug)]
pub enum Item {
    /// A record of another format between states (e.g. a procedure's settings or
    /// measurements), with its line number.
    Record(serde_json::Value, usize),
    /// A state, with the line number of its header and its number of records.
    State(Box<World>, usize, usize),
}

/// Reads a stream of JSON lines that holds several states, each a header and its records as
/// [`write_world`] writes them, with records of other types between them (a `triax` stream):
/// states are read whole, one at a time (memory bounded by one state), and the other records
/// are handed back as they are. Errors name the line in the whole stream.
pub struct StateStream<R: BufRead> {
    input: R,
    line: usize,
    /// A line read ahead (the first after a state), with its number.
    ahead: Option<(String, usize)>,
    done: bool,
}

impl<R: BufRead> StateStream<R> {
    pub fn new(input: R) -> StateStream<R> {
        StateStream {
            input,
            line: 0,
            ahead: None,
            done: false,
        }
    }

    /// The next line that is not blank, with its number; `None` at the end.
    fn next_line(&mut self) -> Result<Option<(String, usize)>, StateError> {
        if let Some(a) = self.ahead.take() {
            return Ok(Some(a));
        }
        loop {
            let mut text = String::new();
            let read = self.input.read_line(&mut text).map_err(|e| {
                if e.kind() == std::io::ErrorKind::InvalidData {
                    at(self.line + 1, "not UTF-8 text")
                } else {
                    StateError::Io(e)
                }
            })?;
            if read == 0 {
                return Ok(None);
            }
            self.line += 1;
            if !text.trim().is_empty() {
                return Ok(Some((text, self.line)));
            }
        }
    }
}

impl<R: BufRead> Iterator for StateStream<R> {
    type Item = Result<Item, StateError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done {
            return None;
        }
        let item = (|| {
            let Some((text, n)) = self.next_line()? else {
                return Ok(None);
            };
            match record_type(&text).as_deref() {
                Some("header") => {}
                Some(_) => {
                    let v = serde_json::from_str(&text)
                        .map_err(|e| at(n, format!("not a JSON record: {e}")))?;
                    return Ok(Some(Item::Record(v, n)));
                }
                None => return Err(at(n, "not a JSON record with a \"type\"")),
            }
            // The state: its header and every state record after it.
            let mut body = text;
            let mut records = 1;
            while let Some((text, m)) = self.next_line()? {
                match record_type(&text) {
                    Some(t) if STATE_RECORDS.contains(&t.as_str()) => {
                        body.push_str(&text);
                        records += 1;
                    }
                    _ => {
                        self.ahead = Some((text, m));
                        break;
                    }
                }
            }
            let world = read_world(body.as_bytes()).map_err(|e| match e {
                StateError::Line { line, msg } => at(line + n - 1, msg),
                e => e,
            })?;
            Ok(Some(Item::State(Box::new(world), n, records)))
        })();
        match item {
            Ok(Some(item)) => Some(Ok(item)),
            Ok(None) => {
                self.done = true;
                None
            }
            Err(e) => {
                self.done = true;
                Some(Err(e))
            }
        }
    }
}

/// Membranes' pins name walls that exist, other than their own, and sliding pins planes; no
/// wall friction beside a membrane; the membranes' kinetic and elastic energy into the audit.
fn check_membranes(world: &mut World) -> Result<(), StateError> {
    let walls = world.walls.len();
    let friction = world.material.wall_friction;
    if friction > 0.0 && world.walls.iter().any(|w| w.membrane.is_some()) {
        // The contact law's shear spring is a spring's (N/m); a membrane's stiffness is a
        // Winkler foundation's (N/m^3), which has no shear law behind it.
        return Err(StateError::Scene(format!(
            "a membrane's contacts are frictionless (its stiffness is per unit volume, with no \
             shear law): the material's wall_friction must be 0 with a membrane wall, got {friction}"
        )));
    }
    let (mut kinetic, mut elastic) = (0.0, 0.0);
    for (k, w) in world.walls.iter().enumerate() {
        let (
            Some(m),
            WallKind::Facets {
                nodes,
                triangles,
                node_velocities,
                ..
            },
        ) = (&w.membrane, &w.kind)
        else {
            continue;
        };
        for p in &m.pins {
            let target = p.wall as usize;
            let why = if target >= walls {
                "names no wall"
            } else if target == k {
                "names its own wall"
            } else if !m.sealed && !matches!(world.walls[target].kind, WallKind::Plane { .. }) {
                "slides on a wall that is not a plane"
            } else {
                continue;
            };
            return Err(StateError::Scene(format!(
                "wall {k}: the membrane's pin of node {} on wall {} {why}",
                p.node, p.wall
            )));
        }
        elastic += m.elastic_energy(nodes, triangles);
        kinetic += crate::dem::membrane::kinetic_energy(m, node_velocities, &world.walls);
    }
    world.energy.membrane_kinetic = kinetic;
    world.energy.membrane_elastic = elastic;
    Ok(())
}

/// An error naming a wall's field `what` if one of `xs` is not finite.
fn all_finite<'a>(what: &str, xs: impl IntoIterator<Item = &'a f64>) -> Result<(), String> {
    match xs.into_iter().find(|x| !x.is_finite()) {
        Some(x) => Err(format!("wall {what} is not finite ({x})")),
        None => Ok(()),
    }
}

/// Records of one kind come with ids 0, 1, 2, ... in order.
fn in_order(n: usize, what: &str, id: u32, expected: usize) -> Result<(), StateError> {
    if id as usize == expected {
        Ok(())
    } else {
        Err(at(
            n,
            format!("{what} id {id} out of order (expected {expected})"),
        ))
    }
}

fn shape_from_record(n: usize, s: ShapeRecord) -> Result<Shape, StateError> {
    if s.vertices.len() > crate::dem::shape::MAX_VERTICES {
        let e = ShapeError::TooManyVertices(crate::text::excerpt(&s.name), s.vertices.len());
        return Err(at(n, e.to_string()));
    }
    let vertices: Vec<Vec3> = s.vertices.iter().map(v3).collect();
    for (i, v) in vertices.iter().enumerate() {
        if !v.iter().all(|x| x.is_finite()) {
            return Err(at(
                n,
                format!("shape '{}' vertex {i} is not finite", s.name),
            ));
        }
    }
    let mut mesh = PolyMesh::from_faces(s.name.clone(), vertices, &s.faces);
    if let Some(p) = s.principal {
        // The exact principal form written by dem: taken as it is, once it is shown to be one.
        mesh.topology(None)
            .map_err(|e| at(n, format!("shape '{}': {}", s.name, e.counted_from(0))))?;
        check_principal(&mesh, &p)
            .map_err(|e| at(n, format!("shape '{}' principal form: {e}", s.name)))?;
        let face_start = std::mem::take(&mut mesh.face_start);
        let face_verts = std::mem::take(&mut mesh.face_verts);
        let (vertex_face_start, vertex_faces) =
            crate::dem::shape::incidence(&face_start, &face_verts);
        let normals: Vec<Vec3> = p.normals.iter().map(v3).collect();
        let climb = crate::dem::shape::Climb::of(
            &mesh.vertices,
            &face_start,
            &face_verts,
            &vertex_face_start,
            &vertex_faces,
            (&normals, &p.offsets),
        );
        return Ok(Shape {
            name: s.name,
            vertices: mesh.vertices,
            face_start,
            face_verts,
            vertex_face_start,
            vertex_faces,
            normals,
            offsets: p.offsets,
            volume: p.volume,
            moments: v3(&p.moments),
            radius: p.radius,
            centroid_in_mesh: v3(&p.centroid_in_mesh),
            frame_in_mesh: UnitQuaternion::new_unchecked(Quaternion::new(
                p.frame_in_mesh[0],
                p.frame_in_mesh[1],
                p.frame_in_mesh[2],
                p.frame_in_mesh[3],
            )),
            climb,
        });
    }
    mesh.topology(None)
        .map_err(|e| at(n, format!("shape '{}': {}", s.name, e.counted_from(0))))?;
    let props = crate::geometry::mass::MassProps::of(&mesh);
    if props.volume <= 0.0 {
        return Err(at(n, format!("shape '{}' faces point inwards (volume {:e}); faces must be counter-clockwise seen from outside", s.name, props.volume)));
    }
    let shape = Shape::from_mesh(&mesh).map_err(|e| at(n, e.to_string()))?;
    // Convex: the hull holds no more volume than the mesh (to rounding).
    if shape.volume > props.volume * (1.0 + 1e-9) {
        return Err(at(
            n,
            format!(
                "shape '{}' is not convex (its hull has {:.6}% more volume); give its convex hull",
                s.name,
                (shape.volume / props.volume - 1.0) * 100.0
            ),
        ));
    }
    Ok(shape)
}

/// A shape's principal form (its vertices in the principal frame, its faces' planes, mass
/// properties) as dem writes it: planes and properties finite, one unit normal per face, the
/// hull convex (every vertex within every face's plane) with each face on its plane, the
/// volume the mesh's own, the radius its farthest vertex, the moments positive and within
/// [`MIN_MOMENT_RATIO`](crate::dem::shape::MIN_MOMENT_RATIO) of each other, the frame a unit
/// quaternion. Read as it is, a form that breaks these would send the engine's climbs and
/// clippings out of the shape's arrays.
fn check_principal(mesh: &PolyMesh, p: &Principal) -> Result<(), String> {
    let faces = mesh.face_count();
    if p.normals.len() != faces || p.offsets.len() != faces {
        return Err(format!(
            "{} normals and {} offsets for {faces} faces",
            p.normals.len(),
            p.offsets.len()
        ));
    }
    let finite = |x: &[f64]| x.iter().all(|v| v.is_finite());
    if !(p.normals.iter().all(|n| finite(n))
        && finite(&p.offsets)
        && finite(&p.moments)
        && finite(&p.centroid_in_mesh)
        && finite(&p.frame_in_mesh)
        && finite(&[p.volume, p.radius]))
    {
        return Err("a number that is not finite".into());
    }
    let far = mesh.vertices.iter().map(|v| v.norm()).fold(0.0, f64::max);
    if !(far > 0.0 && (p.radius - far).abs() <= 1e-9 * far) {
        return Err(format!(
            "radius {:e}, but the farthest vertex is at {far:e}",
            p.radius
        ));
    }
    // A hull's faces merge facets within 1e-10 of its box diagonal (at most 3.5e-10 of `far`)
    // of one plane; then round-off.
    let tol = 1e-8 * far;
    for (f, (n, d)) in p.normals.iter().zip(&p.offsets).enumerate() {
        let n = v3(n);
        if !((n.norm() - 1.0).abs() <= 1e-9) {
            return Err(format!("face {f}'s normal is not a unit vector"));
        }
        if (mesh.face(f).iter()).any(|&v| (n.dot(&mesh.vertices[v as usize]) - d).abs() > tol) {
            return Err(format!("face {f} does not lie on its plane"));
        }
        if mesh.vertices.iter().any(|v| n.dot(v) - d > tol) {
            return Err(format!(
                "a vertex lies outside face {f}'s plane: not convex"
            ));
        }
    }
    let volume = crate::geometry::mass::MassProps::of(mesh).volume;
    if !(p.volume > 0.0 && (p.volume - volume).abs() <= 1e-9 * volume) {
        return Err(format!(
            "volume {:e}, but the faces enclose {volume:e}",
            p.volume
        ));
    }
    let [a, b, c] = p.moments;
    let ratio = crate::dem::shape::MIN_MOMENT_RATIO;
    if !(a > 0.0 && a <= b && b <= c && a >= ratio * c) {
        return Err(format!(
            "moments {a:e}, {b:e}, {c:e}: not ascending, positive and within {ratio:e} of each other"
        ));
    }
    let q = p.frame_in_mesh;
    if !(((q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt() - 1.0).abs() <= 1e-9) {
        return Err("the frame is not a unit quaternion".into());
    }
    Ok(())
}

/// Fixed bodies may not overlap one another (nothing would ever separate them).
fn check_fixed_overlaps(world: &World) -> Result<(), StateError> {
    let fixed: Vec<usize> = (0..world.bodies.len())
        .filter(|&i| world.bodies[i].fixed)
        .collect();
    for (k, &i) in fixed.iter().enumerate() {
        for &j in &fixed[k + 1..] {
            let (a, b) = (&world.bodies[i], &world.bodies[j]);
            let (sa, sb) = (
                &world.shapes[a.shape as usize],
                &world.shapes[b.shape as usize],
            );
            let (pa, pb) = (
                sa.posed(&a.pos, &a.rot, a.scale),
                sb.posed(&b.pos, &b.rot, b.scale),
            );
            if crate::dem::collision::overlap::overlap(sa, &pa, sb, &pb).is_some() {
                return Err(StateError::Scene(format!(
                    "fixed bodies {i} and {j} overlap"
                )));
            }
        }
    }
    Ok(())
}

/// Writes the world as a state: a complete restart point.
pub fn write_world<W: Write>(world: &World, mut out: W) -> std::io::Result<()> {
    let mut line = |r: &Record| -> std::io::Result<()> {
        serde_json::to_writer(&mut out, r)?;
        out.write_all(b"\n")
    };
    line(&Record::Header {
        format: FORMAT.into(),
        version: VERSION,
        units: "SI".into(),
    })?;
    line(&Record::Material(world.material))?;
    line(&Record::Clock {
        time: world.time,
        step: world.step,
        dt: world.dt,
        gravity: a3(&world.gravity),
    })?;
    for (id, s) in world.shapes.iter().enumerate() {
        let q = s.frame_in_mesh.quaternion();
        line(&Record::Shape(ShapeRecord {
            id: id as u32,
            name: s.name.clone(),
            vertices: s.vertices.iter().map(a3).collect(),
            faces: (0..s.face_count()).map(|f| s.face(f).to_vec()).collect(),
            principal: Some(Principal {
                normals: s.normals.iter().map(a3).collect(),
                offsets: s.offsets.clone(),
                volume: s.volume,
                moments: a3(&s.moments),
                radius: s.radius,
                centroid_in_mesh: a3(&s.centroid_in_mesh),
                frame_in_mesh: [q.w, q.i, q.j, q.k],
            }),
        }))?;
    }
    for (id, b) in world.bodies.iter().enumerate() {
        let q = b.rot.quaternion();
        let (mass, moments) = world.inertia_of(b.shape, b.scale);
        let scaled = (b.mass, b.moments) != (mass, moments);
        line(&Record::Body(BodyRecord {
            id: id as u32,
            shape: b.shape,
            scale: b.scale,
            pos: a3(&b.pos),
            rot: [q.w, q.i, q.j, q.k],
            vel: a3(&b.vel),
            ang_mom: a3(&b.ang_mom),
            fixed: b.fixed,
            mass: scaled.then_some(b.mass),
            moments: scaled.then(|| a3(&b.moments)),
        }))?;
    }
    for (id, w) in world.walls.iter().enumerate() {
        line(&Record::Wall(WallRecord::from_wall(id as u32, w)))?;
    }
    for ((partner, body), c) in &world.contacts {
        let partner = match partner {
            Partner::Body(a) => PartnerRecord::Body(*a),
            Partner::Wall(w) => PartnerRecord::Wall(*w),
        };
        line(&Record::Contact(ContactRecord {
            body: *body,
            partner,
            normal: a3(&c.normal),
            point: a3(&c.point),
            depth: c.depth,
            normal_force: c.normal_force,
            potential: Some(c.potential),
            shear: a3(&c.shear),
            sliding: c.sliding,
        }))?;
    }
    let e = &world.energy;
    line(&Record::Energy {
        friction: e.friction,
        damping: e.damping,
        gravity_work: e.gravity_work,
        wall_work: e.wall_work,
        membrane_damping: e.membrane_damping,
        pressure_work: e.pressure_work,
    })?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene() -> String {
        let cube = crate::geometry::mesh::cube(0.5);
        let verts: Vec<[f64; 3]> = cube.vertices.iter().map(a3).collect();
        let faces: Vec<Vec<u32>> = cube.faces().map(|f| f.to_vec()).collect();
        format!(
            "{{\"type\":\"header\",\"format\":\"granular-dem\",\"version\":1,\"units\":\"SI\"}}\n\
             {{\"type\":\"material\",\"density\":2600,\"kn\":1e8,\"ks\":5e7,\"friction\":0.5,\"wall_friction\":0,\"damping\":0.3}}\n\
             {{\"type\":\"clock\",\"time\":0,\"step\":0,\"dt\":0,\"gravity\":[0,0,-9.81]}}\n\
             {{\"type\":\"shape\",\"id\":0,\"name\":\"cube\",\"vertices\":{},\"faces\":{}}}\n\
             {{\"type\":\"wall\",\"id\":0,\"kind\":\"plane\",\"normal\":[0,0,1],\"offset\":0}}\n\
             {{\"type\":\"body\",\"id\":0,\"shape\":0,\"scale\":0.02,\"pos\":[0,0,0.009999998]}}\n\
             {{\"type\":\"body\",\"id\":1,\"shape\":0,\"scale\":0.02,\"pos\":[0.003,0,0.0301],\"vel\":[0,0,-0.1]}}\n",
            serde_json::to_string(&verts).unwrap(),
            serde_json::to_string(&faces).unwrap()
        )
    }

    #[test]
    fn a_state_round_trips_exactly() {
        let mut w = read_world(scene().as_bytes()).unwrap();
        w.dt = 0.2 * w.critical_dt();
        for _ in 0..20_000 {
            w.step();
        }
        assert!(
            w.contacts.len() == 2,
            "a wall and a body contact: {}",
            w.contacts.len()
        );
        let mut a = Vec::new();
        write_world(&w, &mut a).unwrap();
        let back = read_world(a.as_slice()).unwrap();
        let mut b = Vec::new();
        write_world(&back, &mut b).unwrap();
        assert_eq!(String::from_utf8(a).unwrap(), String::from_utf8(b).unwrap());
    }

    /// The scene with its plane replaced by a floor of facets under a cylinder.
    fn walled_scene() -> String {
        scene().replace(
            r#"{"type":"wall","id":0,"kind":"plane","normal":[0,0,1],"offset":0}"#,
            concat!(
                r#"{"type":"wall","id":0,"kind":"facets","nodes":[[-1,-1,0],[1,-1,0],[1,1,0],[-1,1,0]],"triangles":[[0,1,2],[0,2,3]],"node_velocities":[[0,0,0],[0,0,0],[0,0,1e-4],[0,0,0]]}"#,
                "\n",
                r#"{"type":"wall","id":1,"kind":"cylinder","point":[0.0015,0,-0.1],"axis":[0,0,1],"radius":0.01527,"height":1,"segments":64,"radial_rate":-5e-4}"#
            ),
        )
    }

    #[test]
    fn facet_and_cylinder_walls_round_trip_exactly() {
        let mut w = read_world(walled_scene().as_bytes()).unwrap();
        w.dt = 0.2 * w.critical_dt();
        // Body 0 comes to rest on the facets and the shrinking cylinder reaches the bodies
        // (first after about 20 000 steps; the contact is light and comes and goes).
        let both = |w: &World| {
            w.contacts.contains_key(&(Partner::Wall(0), 0))
                && w.contacts.keys().any(|k| k.0 == Partner::Wall(1))
        };
        for _ in 0..20_000 {
            w.step();
        }
        for _ in 0..20_000 {
            if both(&w) {
                break;
            }
            w.step();
        }
        assert!(both(&w), "{:?}", w.contacts.keys().collect::<Vec<_>>());
        let mut a = Vec::new();
        write_world(&w, &mut a).unwrap();
        let mut back = read_world(a.as_slice()).unwrap();
        let mut b = Vec::new();
        write_world(&back, &mut b).unwrap();
        assert_eq!(String::from_utf8(a).unwrap(), String::from_utf8(b).unwrap());
        // And it continues identically.
        for _ in 0..100 {
            w.step();
            back.step();
        }
        let (mut a, mut b) = (Vec::new(), Vec::new());
        write_world(&w, &mut a).unwrap();
        write_world(&back, &mut b).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn bad_walls_are_named() {
        let good = walled_scene();
        let cases = [
            (
                r#""kind":"facets""#,
                r#""kind":"sphere""#,
                "wall kind 'sphere' is not known",
            ),
            (
                r#""triangles":[[0,1,2],[0,2,3]]"#,
                r#""triangles":[[0,1,2],[0,2,9]]"#,
                "triangle 1 uses node 9",
            ),
            (
                r#""triangles":[[0,1,2],[0,2,3]]"#,
                r#""triangles":[[0,1,2],[0,2,2]]"#,
                "triangle 1 has no area",
            ),
            (
                r#"[0,0,1e-4],[0,0,0]]"#,
                r#"[0,0,1e-4]]"#,
                "node_velocities has 3 entries for 4 nodes",
            ),
            (r#""radius":0.01527"#, r#""radius":-1"#, "positive radius"),
            (r#""segments":64"#, r#""segments":2"#, "at least 3 segments"),
            (
                r#""axis":[0,0,1]"#,
                r#""axis":[0,0,2]"#,
                "axis has length 2",
            ),
            (r#""axis":[0,0,1],"#, "", "needs 'axis'"),
            (
                r#""height":1"#,
                r#""height":1,"normal":[0,0,1]"#,
                "a cylinder wall has no field 'normal'",
            ),
            (r#""radius":0.01527"#, r#""radius":NaN"#, "line 6"),
        ];
        for (from, to, expect) in cases {
            assert!(good.contains(from), "{from}");
            let e = error_of(&good.replacen(from, to, 1));
            assert!(e.contains(expect), "{to}: {e}");
            assert!(e.starts_with("line"), "{e}");
        }
    }

    fn error_of(text: &str) -> String {
        read_world(text.as_bytes()).unwrap_err().to_string()
    }

    #[test]
    fn bad_scenes_name_the_line() {
        let good = scene();
        let lines: Vec<&str> = good.lines().collect();
        let with = |k: usize, new: &str| {
            let mut l = lines.clone();
            l[k] = new;
            l.join("\n")
        };
        assert!(error_of(&with(
            0,
            r#"{"type":"header","format":"granular-dem","version":7,"units":"SI"}"#
        ))
        .contains("line 1: version 7"));
        assert!(error_of(&with(
            5,
            r#"{"type":"body","id":0,"shape":0,"pos":[0,0,0]}"#
        ))
        .contains("line 6: missing field `scale`"));
        assert!(error_of(&with(
            5,
            r#"{"type":"body","id":0,"shape":0,"scale":0,"pos":[0,0,0]}"#
        ))
        .contains("line 6: body 0 has scale 0"));
        assert!(error_of(&with(
            5,
            r#"{"type":"body","id":0,"shape":0,"scale":1,"pos":[0,0,1e999]}"#
        ))
        .contains("line 6"));
        assert!(error_of(&with(
            5,
            r#"{"type":"body","id":0,"shape":3,"scale":1,"pos":[0,0,0]}"#
        ))
        .contains("shape 3"));
        let truncated = &good[..good.len() - 20];
        assert!(
            error_of(truncated).contains("line 7"),
            "{}",
            error_of(truncated)
        );
        assert!(error_of("").contains("empty"));
        assert!(error_of(&with(1, r#"{"type":"material","density":2600}"#)).contains("line 2"));
        // An inside-out cube: faces reversed.
        let inside_out = good
            .replace("[0,2,3,1]", "[1,3,2,0]")
            .replace("[4,5,7,6]", "[6,7,5,4]")
            .replace("[0,1,5,4]", "[4,5,1,0]")
            .replace("[2,6,7,3]", "[3,7,6,2]")
            .replace("[0,4,6,2]", "[2,6,4,0]")
            .replace("[1,3,7,5]", "[5,7,3,1]");
        assert!(
            error_of(&inside_out).contains("inwards"),
            "{}",
            error_of(&inside_out)
        );
        // Two fixed bodies overlapping.
        let fixed = with(6, r#"{"type":"body","id":1,"shape":0,"scale":0.02,"pos":[0.003,0,0.009999998],"fixed":true}"#).replace(r#""pos":[0,0,0.009999998]}"#, r#""pos":[0,0,0.009999998],"fixed":true}"#);
        assert!(
            error_of(&fixed).contains("fixed bodies 0 and 1 overlap"),
            "{}",
            error_of(&fixed)
        );
    }

    /// A principal form that is not one (as a fuzzer made: a face naming vertex 71 of 16) is
    /// refused on reading, with what is wrong, instead of being taken as it is.
    #[test]
    fn a_principal_form_that_is_not_one_is_refused() {
        let mut out = Vec::new();
        write_world(&read_world(scene().as_bytes()).unwrap(), &mut out).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(read_world(text.as_bytes()).is_ok());
        let broken = |change: &dyn Fn(&mut serde_json::Value)| {
            let lines = text.lines().map(|l| {
                let mut r: serde_json::Value = serde_json::from_str(l).unwrap();
                if r["type"] == "shape" {
                    change(&mut r);
                }
                r.to_string()
            });
            error_of(&lines.collect::<Vec<_>>().join("\n"))
        };
        let cases: [(&dyn Fn(&mut serde_json::Value), &str); 8] = [
            (
                &|r| r["faces"][0][0] = 71.into(),
                "face 0 uses vertex 71 which does not exist",
            ),
            (
                &|r| {
                    r["principal"]["normals"].as_array_mut().unwrap().pop();
                },
                "5 normals and 6 offsets for 6 faces",
            ),
            (
                &|r| {
                    let x = r["principal"]["normals"][0][0].as_f64().unwrap();
                    r["principal"]["normals"][0][0] = (x * 1.1 + 0.1).into();
                },
                "face 0's normal is not a unit vector",
            ),
            (
                &|r| {
                    let d = r["principal"]["offsets"][0].as_f64().unwrap();
                    r["principal"]["offsets"][0] = (d + 0.01).into();
                },
                "face 0 does not lie on its plane",
            ),
            (
                &|r| {
                    let x = r["principal"]["radius"].as_f64().unwrap();
                    r["principal"]["radius"] = (2.0 * x).into();
                },
                "but the farthest vertex is at",
            ),
            (
                &|r| {
                    let x = r["principal"]["volume"].as_f64().unwrap();
                    r["principal"]["volume"] = (2.0 * x).into();
                },
                "but the faces enclose",
            ),
            (
                &|r| r["principal"]["moments"] = serde_json::json!([3.0, 2.0, 1.0]),
                "not ascending, positive",
            ),
            (
                &|r| r["principal"]["frame_in_mesh"] = serde_json::json!([2.0, 0.0, 0.0, 0.0]),
                "the frame is not a unit quaternion",
            ),
        ];
        for (change, says) in cases {
            let e = broken(change);
            assert!(
                e.contains("shape 'cube'") && e.contains(says),
                "{says}: {e}"
            );
        }
    }

    #[test]
    fn a_non_convex_shape_is_rejected() {
        // An L-shaped prism.
        let pts = [(0., 0.), (2., 0.), (2., 1.), (1., 1.), (1., 2.), (0., 2.)];
        let mut v: Vec<[f64; 3]> = pts.iter().map(|&(x, y)| [x, y, 0.0]).collect();
        v.extend(pts.iter().map(|&(x, y)| [x, y, 1.0]));
        let mut faces = vec![vec![5, 4, 3, 2, 1, 0], vec![6, 7, 8, 9, 10, 11]];
        for i in 0..6u32 {
            let j = (i + 1) % 6;
            faces.push(vec![i, j, j + 6, i + 6]);
        }
        let rec = format!(
            "{{\"type\":\"shape\",\"id\":0,\"name\":\"L\",\"vertices\":{},\"faces\":{}}}",
            serde_json::to_string(&v).unwrap(),
            serde_json::to_string(&faces).unwrap()
        );
        let text = scene()
            .lines()
            .enumerate()
            .map(|(k, l)| if k == 3 { rec.clone() } else { l.to_string() })
            .collect::<Vec<_>>()
            .join("\n");
        assert!(
            error_of(&text).contains("line 4: shape 'L' is not convex"),
            "{}",
            error_of(&text)
        );
    }
}
