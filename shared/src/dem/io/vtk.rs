//! VTK XML snapshots for ParaView: particle surfaces (`.vtu`, polygons with body id and
//! velocity), the contact network (lines from body to partner with normal force, shear force and
//! the sliding flag), walls (a square patch of each plane), and a `.pvd` collection per stream
//! that ParaView opens as a time series. ASCII, so the files are readable and diffable.

use crate::dem::contacts::Partner;
use crate::dem::wall::WallKind;
use crate::dem::world::World;
use crate::math::{basis, Vec3};
use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Collects snapshots of one run in a directory and writes the `.pvd` collections.
pub struct Snapshots {
    dir: PathBuf,
    entries: Vec<(f64, usize)>,
}

fn data_array(out: &mut String, name: &str, components: usize, values: impl Iterator<Item = f64>) {
    let _ = write!(out, "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"{components}\" format=\"ascii\">");
    for v in values {
        let _ = write!(out, "{v} ");
    }
    out.push_str("</DataArray>\n");
}

fn int_array(out: &mut String, name: &str, values: impl Iterator<Item = i64>) {
    let _ = write!(
        out,
        "<DataArray type=\"Int64\" Name=\"{name}\" format=\"ascii\">"
    );
    for v in values {
        let _ = write!(out, "{v} ");
    }
    out.push_str("</DataArray>\n");
}

/// An unstructured grid of `points` and cells (`connectivity` lists, one VTK `cell_type`), with
/// cell data arrays already formatted.
fn unstructured(points: &[Vec3], cells: &[Vec<usize>], cell_type: u8, cell_data: &str) -> String {
    let mut s = String::new();
    s.push_str("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n<UnstructuredGrid>\n");
    let _ = writeln!(
        s,
        "<Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">",
        points.len(),
        cells.len()
    );
    s.push_str("<Points>\n");
    data_array(
        &mut s,
        "Points",
        3,
        points.iter().flat_map(|p| [p.x, p.y, p.z]),
    );
    s.push_str("</Points>\n<Cells>\n");
    int_array(
        &mut s,
        "connectivity",
        cells.iter().flatten().map(|&i| i as i64),
    );
    let mut offset = 0;
    int_array(
        &mut s,
        "offsets",
        cells.iter().map(|c| {
            offset += c.len() as i64;
            offset
        }),
    );
    let _ = write!(
        s,
        "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">"
    );
    for _ in cells {
        let _ = write!(s, "{cell_type} ");
    }
    s.push_str("</DataArray>\n</Cells>\n<CellData>\n");
    s.push_str(cell_data);
    s.push_str("</CellData>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n");
    s
}

/// The particle surfaces: one polygon per face, cell data `id` and `velocity`.
pub fn particles_vtu(world: &World) -> String {
    let (mut points, mut cells, mut ids, mut vels) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, b) in world.bodies.iter().enumerate() {
        let shape = &world.shapes[b.shape as usize];
        let posed = shape.posed(&b.pos, &b.rot, b.scale);
        let base = points.len();
        points.extend_from_slice(&posed.vertices);
        for f in 0..shape.face_count() {
            cells.push(shape.face(f).iter().map(|&v| base + v as usize).collect());
            ids.push(i as i64);
            vels.push(b.vel);
        }
    }
    let mut data = String::new();
    int_array(&mut data, "id", ids.into_iter());
    data_array(
        &mut data,
        "velocity",
        3,
        vels.iter().flat_map(|v| [v.x, v.y, v.z]),
    );
    unstructured(&points, &cells, 7, &data)
}

/// The contact network: a line from the partner (body centroid, or the contact point for a
/// wall) to the body's centroid, with `normal_force`, `shear_force` and `sliding`.
pub fn contacts_vtu(world: &World) -> String {
    let (mut points, mut cells) = (Vec::new(), Vec::new());
    let (mut fns, mut shears, mut sliding) = (Vec::new(), Vec::new(), Vec::new());
    for ((partner, body), c) in &world.contacts {
        let from = match partner {
            Partner::Body(a) => world.bodies[*a as usize].pos,
            Partner::Wall(_) => c.point,
        };
        points.push(from);
        points.push(world.bodies[*body as usize].pos);
        cells.push(vec![points.len() - 2, points.len() - 1]);
        fns.push(c.normal_force);
        shears.push(c.shear);
        sliding.push(c.sliding as i64);
    }
    let mut data = String::new();
    data_array(&mut data, "normal_force", 1, fns.into_iter());
    data_array(
        &mut data,
        "shear_force",
        3,
        shears.iter().flat_map(|v| [v.x, v.y, v.z]),
    );
    int_array(&mut data, "sliding", sliding.into_iter());
    unstructured(&points, &cells, 3, &data)
}

/// The walls: a square patch of each plane around the bodies, the triangles of facet walls,
/// the segments of cylinders; cell data `force` (what the particles push on the wall, shared
/// among its cells by area).
pub fn walls_vtu(world: &World) -> String {
    let centres: Vec<Vec3> = world.bodies.iter().map(|b| b.pos).collect();
    let (lo, hi) = crate::math::bounding_box(&centres).unwrap_or((Vec3::zeros(), Vec3::zeros()));
    let centre = (lo + hi) / 2.0;
    let half = ((hi - lo).norm() / 2.0).max(1e-3) * 1.2;
    let (mut points, mut cells, mut forces) = (Vec::new(), Vec::new(), Vec::new());
    for w in &world.walls {
        let base = points.len();
        match &w.kind {
            WallKind::Plane { normal: n, offset } => {
                let p = centre - n * (n.dot(&centre) - offset);
                let (u, v) = basis(n);
                let (u, v) = (u * half, v * half);
                points.extend([p - u - v, p + u - v, p + u + v, p - u + v]);
                cells.push((base..base + 4).collect());
                forces.push(w.force);
            }
            WallKind::Facets {
                nodes, triangles, ..
            } => {
                // Each triangle carries the wall's total force spread by area (the per-node
                // forces are in the state).
                points.extend(nodes);
                let area: Vec<f64> = triangles
                    .iter()
                    .map(|t| {
                        let [a, b, c] = t.map(|i| nodes[i as usize]);
                        (b - a).cross(&(c - a)).norm() / 2.0
                    })
                    .collect();
                let total: f64 = area.iter().sum();
                for (t, a) in triangles.iter().zip(&area) {
                    cells.push(t.iter().map(|&i| base + i as usize).collect());
                    forces.push(w.force * (a / total));
                }
            }
            WallKind::Cylinder {
                point,
                axis,
                radius,
                height,
                segments,
                ..
            } => {
                let (e1, e2) = basis(axis);
                let n = *segments as usize;
                for j in 0..n {
                    let a = j as f64 * std::f64::consts::TAU / n as f64;
                    let p = point + (e1 * a.cos() + e2 * a.sin()) * *radius;
                    points.extend([p, p + axis * *height]);
                }
                for j in 0..n {
                    let k = (j + 1) % n;
                    cells.push(vec![
                        base + 2 * j,
                        base + 2 * j + 1,
                        base + 2 * k + 1,
                        base + 2 * k,
                    ]);
                    forces.push(w.force / n as f64);
                }
            }
        }
    }
    let mut data = String::new();
    data_array(
        &mut data,
        "force",
        3,
        forces.iter().flat_map(|f| [f.x, f.y, f.z]),
    );
    unstructured(&points, &cells, 7, &data)
}

impl Snapshots {
    /// Snapshots into `dir` (created if missing).
    pub fn new(dir: &Path) -> std::io::Result<Snapshots> {
        std::fs::create_dir_all(dir)?;
        Ok(Snapshots {
            dir: dir.to_path_buf(),
            entries: Vec::new(),
        })
    }

    /// Snapshots into `dir` that go on from a run's `earlier` ones (their times, in order):
    /// the next is numbered after them, and the collections list them all.
    pub fn continuing(dir: &Path, earlier: &[f64]) -> std::io::Result<Snapshots> {
        let mut s = Snapshots::new(dir)?;
        s.entries = earlier.iter().copied().zip(0..).collect();
        Ok(s)
    }

    /// Writes the particles, contacts and walls of the world now.
    pub fn write(&mut self, world: &World) -> std::io::Result<()> {
        let k = self.entries.len();
        for (stream, text) in [
            ("particles", particles_vtu(world)),
            ("contacts", contacts_vtu(world)),
            ("walls", walls_vtu(world)),
        ] {
            std::fs::write(self.dir.join(format!("{stream}_{k:06}.vtu")), text)?;
        }
        self.entries.push((world.time, k));
        self.write_collections()
    }

    fn write_collections(&self) -> std::io::Result<()> {
        for stream in ["particles", "contacts", "walls"] {
            let mut f = std::io::BufWriter::new(std::fs::File::create(
                self.dir.join(format!("{stream}.pvd")),
            )?);
            writeln!(f, "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"1.0\">\n<Collection>")?;
            for (t, k) in &self.entries {
                writeln!(
                    f,
                    "<DataSet timestep=\"{t}\" part=\"0\" file=\"{stream}_{k:06}.vtu\"/>"
                )?;
            }
            writeln!(f, "</Collection>\n</VTKFile>")?;
            f.flush()?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::law::Material;
    use crate::dem::shape::Shape;
    use crate::dem::wall::Wall;
    use nalgebra::UnitQuaternion;

    /// The numbers inside the `Name` data array of the first piece.
    fn array(text: &str, name: &str) -> Vec<f64> {
        let start = text
            .find(&format!("Name=\"{name}\""))
            .expect("array present");
        let open = start + text[start..].find('>').unwrap() + 1;
        let close = open + text[open..].find("</DataArray>").unwrap();
        text[open..close]
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect()
    }

    #[test]
    fn counts_agree_with_the_header() {
        let mut w = World::new(Material::default(), Vec3::new(0.0, 0.0, -9.81));
        let s = w.add_shape(Shape::from_mesh(&crate::geometry::mesh::cube(0.5)).unwrap());
        w.walls.push(Wall::plane(Vec3::zeros(), Vec3::z()));
        w.add_body(
            s,
            0.02,
            Vec3::new(0.0, 0.0, 0.0099),
            UnitQuaternion::identity(),
        );
        w.add_body(
            s,
            0.02,
            Vec3::new(0.0, 0.0, 0.0298),
            UnitQuaternion::identity(),
        );
        w.dt = 1e-7;
        w.step();
        let p = particles_vtu(&w);
        assert!(p.contains("NumberOfPoints=\"16\" NumberOfCells=\"12\""));
        assert_eq!(array(&p, "Points").len(), 48);
        assert_eq!(array(&p, "connectivity").len(), 48);
        assert_eq!(array(&p, "offsets").last(), Some(&48.0));
        assert_eq!(
            array(&p, "id"),
            [0.0; 6]
                .iter()
                .chain(&[1.0; 6])
                .copied()
                .collect::<Vec<_>>()
        );
        let c = contacts_vtu(&w);
        assert!(c.contains("NumberOfCells=\"2\""), "{c}");
        assert_eq!(array(&c, "normal_force").len(), 2);
        assert!(array(&c, "normal_force").iter().all(|&f| f > 0.0));
        let wl = walls_vtu(&w);
        assert!(wl.contains("NumberOfPoints=\"4\" NumberOfCells=\"1\""));
    }
}
