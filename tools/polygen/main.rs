//! polygen: random convex polyhedra from tangent planes of a sphere, as an OBJ stream.

use anyhow::Context;
use clap::Parser;
use rayon::prelude::*;
use shared::cli;
use shared::geometry::mesh::PolyMesh;
use shared::geometry::obj::ObjWriter;
use shared::geometry::polygen::{self, Params, Redraws};
use std::io::Write;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7                       the paper's nine templates
  polygen --faces 6..14 --seed 7 | abrade --levels 3 | roundness
  polygen --faces 10 --count 1000 --max-elongation inf > many.obj

Each object is named pK_I (K faces, index I) and carries '#@ k= seed= index= redraws=
elongation=' attributes. Face i lies in the tangent plane at random point i. A draw is redrawn
when the polyhedron is unbounded (the points do not surround the centre), degenerate (two points
closer than 1e-6 R) or longer than --max-elongation; the total is the last comment line.
See docs/formats/obj-stream.md and docs/models/polygen.md.";

/// Random convex polyhedra: k points uniform on a sphere of radius R, the polyhedron is the
/// intersection of the half-spaces below their tangent planes (exact polar dual of the points'
/// hull). Writes an OBJ stream to standard output.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Face count K, or an inclusive range A..B (one family per count, in order)
    #[arg(long, default_value = "6..14", value_parser = cli::parse_range::<usize>)]
    faces: (usize, usize),
    /// Polyhedra per face count
    #[arg(long, default_value_t = 1)]
    count: u64,
    /// The largest face count --faces may ask for
    #[arg(long, default_value_t = 100_000)]
    max_faces: usize,
    /// Random seed; same seed, same bytes, on any machine and thread count
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Sphere radius R (the inscribed radius of every polyhedron)
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    radius: f64,
    /// Redraw polyhedra whose farthest vertex is beyond this many R ('inf': no cap)
    #[arg(long, default_value_t = polygen::DEFAULT_MAX_ELONGATION, allow_negative_numbers = true)]
    max_elongation: f64,
    /// Also emit the construction (sphere and tangent-plane patches) for pictures; these extra
    /// objects are open meshes, for `render` only
    #[arg(long)]
    construction: bool,
}

fn main() -> ExitCode {
    cli::run("polygen", || run(Cli::parse()))
}

fn run(args: Cli) -> anyhow::Result<()> {
    let (k0, k1) = args.faces;
    if args.count == 0 {
        return Err(cli::usage("--count must be at least 1"));
    }
    if k1 > args.max_faces {
        return Err(cli::usage(format!(
            "--faces {k1}: more than --max-faces {} (a polyhedron of k faces takes about 600 k bytes while it is made)",
            args.max_faces
        )));
    }
    Params {
        faces: k0,
        radius: args.radius,
        max_elongation: args.max_elongation,
    }
    .check()
    .map_err(|e| cli::usage(e.to_string()))?;
    // The jobs in order, made 512 at a time: memory does not grow with --count.
    let total_jobs = (k1 + 1).saturating_sub(k0) as u128 * args.count as u128;
    let mut jobs = (k0..=k1).flat_map(|k| (0..args.count).map(move |i| (k, i)));
    let mut chunk = Vec::with_capacity(512);
    let mut done = 0u64;
    let mut out = ObjWriter::new(cli::stdout());
    out.comment(&cli::provenance("polygen"))?;
    out.comment(&format!(
        " polygen rule: points uniform on the sphere; redraw if unbounded, degenerate or elongation > {}",
        args.max_elongation
    ))?;
    let mut total = Redraws::default();
    let progress = cli::Progress::new("polygen");
    loop {
        chunk.clear();
        chunk.extend(jobs.by_ref().take(512));
        if chunk.is_empty() {
            break;
        }
        let made: Vec<_> = chunk
            .par_iter()
            .map(|&(k, i)| {
                let params = Params {
                    faces: k,
                    radius: args.radius,
                    max_elongation: args.max_elongation,
                };
                polygen::generate(&params, args.seed, i)
                    .with_context(|| format!("polyhedron p{k:02}_{i}"))
            })
            .collect();
        for p in made {
            let p = p?;
            total.add(&p.redraws);
            if args.construction {
                for m in construction(&p.mesh, &p.tangent_points, args.radius) {
                    out.object(&m, &[])?;
                }
            } else {
                out.object(&p.mesh, &[])?;
            }
        }
        done += chunk.len() as u64;
        progress.tick(done, u64::try_from(total_jobs).ok(), "polyhedra");
    }
    progress.finish();
    out.comment(&format!(
        " polygen redraws: {} in all ({} unbounded, {} degenerate, {} elongated) for {} polyhedra",
        total.total(),
        total.unbounded,
        total.degenerate,
        total.elongated,
        total_jobs
    ))?;
    out.into_inner()?.flush()?;
    Ok(())
}

/// The polyhedron plus its construction for a picture: two cells, "NAME: sphere and tangent
/// planes" and "NAME: polyhedron".
fn construction(poly: &PolyMesh, points: &[shared::math::Vec3], r: f64) -> Vec<PolyMesh> {
    let cell_a = format!("{}: sphere and tangent planes", poly.name);
    let cell_b = format!("{}: polyhedron", poly.name);
    let mut out = Vec::new();
    let mut sphere = shared::draw::render::uv_sphere(r, 24, 48);
    sphere.name = format!("{cell_a}/sphere");
    sphere.attrs.set("color", "c8c8d2");
    sphere.attrs.set("edges", "no");
    out.push(sphere);
    for (i, p) in points.iter().enumerate() {
        let n = p.normalize();
        let u = shared::math::basis(&n).0 * (0.6 * r);
        let w = n.cross(&u);
        let c = p * 1.002;
        let mut patch = PolyMesh::from_faces(
            format!("{cell_a}/plane{i}"),
            vec![c - u - w, c + u - w, c + u + w, c - u + w],
            &[vec![0, 1, 2, 3]],
        );
        patch.attrs.set("color", "3c78c8");
        out.push(patch);
    }
    let mut body = poly.clone();
    body.name = format!("{cell_b}/{}", poly.name);
    body.attrs.set("color", "e08c3c");
    out.push(body);
    out
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_well_formed() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
