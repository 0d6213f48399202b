//! roundness: volume, area and Barrett's roundness S3D of each object, and of its convex hull.

use anyhow::Context;
use clap::{Parser, ValueEnum};
use serde::Serialize;
use shared::cli::{self, Emit};
use shared::geometry::hull::convex_hull;
use shared::geometry::mass::MassProps;
use std::io::Write;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7 | abrade --levels 3 | roundness
  roundness --format jsonl < shapes.obj

Columns: name, k (template face count, from polygen's attributes; empty if unknown), level
(abrasion level, from abrade's attributes; 0 if unknown), vertices, faces, volume, area,
s3d = (36 pi V^2)^(1/3) / A, d_eq (diameter of the sphere of equal volume), then the same for
the object's convex hull (hull_vertices, hull_faces, hull_volume, hull_area, hull_s3d): the hull
is the shape a rigid-body simulation uses. Units are those of the coordinates.

Non-planar faces (after abrasion) are split into a fan of triangles about the face's vertex
centroid; a once-abraded cube gives S3D = 0.953 this way (0.936 or 0.965 with the two diagonal
splits of its quads). Open, non-manifold or inward-facing meshes are errors.";

#[derive(Clone, Copy, Debug, ValueEnum)]
enum Format {
    Csv,
    Jsonl,
}

/// Roundness S3D (Barrett) and mass properties of each object of an OBJ stream on standard
/// input, one row per object, in input order.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Output format
    #[arg(long, value_enum, default_value_t = Format::Csv)]
    format: Format,
}

#[derive(Serialize)]
struct Row {
    name: String,
    k: Option<u32>,
    level: u32,
    vertices: usize,
    faces: usize,
    volume: f64,
    area: f64,
    s3d: f64,
    d_eq: f64,
    hull_vertices: usize,
    hull_faces: usize,
    hull_volume: f64,
    hull_area: f64,
    hull_s3d: f64,
}

fn main() -> ExitCode {
    cli::run("roundness", || run(Cli::parse()))
}

fn measure(obj: shared::geometry::obj::ObjObject) -> anyhow::Result<Row> {
    let what = || format!("object '{}' (line {})", obj.mesh.name, obj.line);
    let m = &obj.mesh;
    let props = cli::solid(&obj)?;
    let hull = convex_hull(&m.vertices).with_context(what)?;
    let hp = MassProps::of(&hull.mesh);
    Ok(Row {
        name: m.name.clone(),
        k: m.attrs.get("k").and_then(|k| k.parse().ok()),
        level: m
            .attrs
            .get("level")
            .and_then(|l| l.parse().ok())
            .unwrap_or(0),
        vertices: m.vertices.len(),
        faces: m.face_count(),
        volume: props.volume,
        area: props.area,
        s3d: props.s3d(),
        d_eq: props.equivalent_diameter(),
        hull_vertices: hull.mesh.vertices.len(),
        hull_faces: hull.mesh.face_count(),
        hull_volume: hp.volume,
        hull_area: hp.area,
        hull_s3d: hp.s3d(),
    })
}

fn run(args: Cli) -> anyhow::Result<()> {
    let mut csv_out = csv::Writer::from_writer(cli::stdout());
    let mut json_out = cli::stdout();
    let n = cli::for_each_object("roundness", cli::stdin(), 64, measure, |e| {
        if let Emit::Done(row) = e {
            match args.format {
                Format::Csv => csv_out.serialize(&row)?,
                Format::Jsonl => {
                    serde_json::to_writer(&mut json_out, &row)?;
                    json_out.write_all(b"\n")?;
                }
            }
        }
        Ok(())
    })?;
    cli::require_objects(n)?;
    csv_out.flush()?;
    json_out.flush()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_well_formed() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
