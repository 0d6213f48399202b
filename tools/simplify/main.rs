//! simplify: the convex hull of every object of an OBJ stream, cut to a vertex budget.

use anyhow::Context;
use clap::Parser;
use shared::cli;
use shared::geometry::hull;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7 | abrade --levels 3 | simplify --vertices 100 > ab3_100.obj
  simplify --vertices 50 < ab3.obj | roundness        S3D of the simplified hulls

Each object is replaced by the convex hull of at most N of its hull vertices (what the DEM
engine uses of a shape anyway is its hull). The vertices are chosen greedily: from the
tetrahedron of extreme points, the vertex farthest outside the current hull is added until N
are in, so the simplified hull lies inside the full one and the largest distance of a left-out
vertex shrinks fastest. Objects whose hull has N vertices or fewer come out as their full hull.
Name and attributes are kept; attribute hull_vertices= records the count. Input as for abrade
(closed, consistently oriented meshes); a bad object stops the run with a message naming the
object and line, the objects before it written whole.";

/// The convex hull of each object of an OBJ stream (standard input), with at most --vertices
/// vertices; the result goes to standard output.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Vertex budget N per object (at least 4)
    #[arg(long)]
    vertices: usize,
}

fn main() -> ExitCode {
    cli::run("simplify", || run(Cli::parse()))
}

fn run(args: Cli) -> anyhow::Result<()> {
    if args.vertices < 4 {
        return Err(cli::usage(format!(
            "--vertices must be at least 4 (a tetrahedron), got {}",
            args.vertices
        )));
    }
    let mut out = cli::ObjOut::new("simplify", cli::stdout());
    let n = cli::for_each_object(
        "simplify",
        cli::stdin(),
        64,
        |obj| {
            let what = || format!("object '{}' (line {})", obj.mesh.name, obj.line);
            obj.mesh
                .topology(Some(&obj.face_lines))
                .with_context(what)?;
            let h = hull::simplified_hull(&obj.mesh.vertices, args.vertices).with_context(what)?;
            let mut m = h.mesh;
            m.name = obj.mesh.name.clone();
            m.attrs = obj.mesh.attrs.clone();
            m.attrs.set("hull_vertices", m.vertices.len());
            Ok((vec![m], obj.comments))
        },
        |e| Ok(out.emit(e)?),
    )?;
    cli::require_objects(n)?;
    out.finish()?;
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
