//! abrade: Catmull-Clark subdivision of every object of an OBJ stream (the paper's abrasion).

use anyhow::Context;
use clap::Parser;
use shared::cli;
use shared::geometry::mesh::PolyMesh;
use shared::geometry::subdiv;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7 | abrade --levels 3 > ab3.obj
  abrade --levels 0..3 < cube.obj | render --cols 4 > cube.png   every level, named NAME_abL

Input: any closed, consistently oriented 2-manifold polygon mesh per object (n-gons, any valence,
convexity not required). Output: quads, orientation kept; attribute level= raised by the levels
applied. A bad object (open, non-manifold, flipped face, face with fewer than 3 distinct vertices,
bad index, non-finite coordinate) stops the run with a message naming the object and line;
objects before it are written whole, nothing of it is.";

/// Catmull-Clark subdivision (the paper's Eqs. 4-6) of each object of an OBJ stream read from
/// standard input; the result goes to standard output.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Subdivision levels L, or an inclusive range A..B to emit every level from A to B
    #[arg(long, default_value = "1", value_parser = cli::parse_range::<u32>)]
    levels: (u32, u32),
}

fn main() -> ExitCode {
    cli::run("abrade", || run(Cli::parse()))
}

fn run(args: Cli) -> anyhow::Result<()> {
    let (l0, l1) = args.levels;
    if l1 > 6 {
        return Err(cli::usage(format!(
            "--levels {l1} is too many: each level multiplies the faces by about 4 (at most 6)"
        )));
    }
    let named = l0 != l1;
    let mut out = cli::ObjOut::new("abrade", cli::stdout());
    let n = cli::for_each_object(
        "abrade",
        cli::stdin(),
        64,
        |obj| {
            let topo = obj
                .mesh
                .topology(Some(&obj.face_lines))
                .with_context(|| format!("object '{}' (line {})", obj.mesh.name, obj.line))?;
            let base_level: u32 = obj
                .mesh
                .attrs
                .get("level")
                .and_then(|l| l.parse().ok())
                .unwrap_or(0);
            let mut levels = Vec::new();
            let mut cur = subdiv::subdivide(&obj.mesh, &topo, l0);
            for l in l0..=l1 {
                if l > l0 {
                    let t = cur
                        .topology(None)
                        .expect("Catmull-Clark keeps a closed oriented manifold");
                    cur = subdiv::catmull_clark(&cur, &t);
                }
                let mut m: PolyMesh = cur.clone();
                m.attrs.set("level", base_level + l);
                if named {
                    m.name = format!("{}_ab{l}", obj.mesh.name);
                }
                levels.push(m);
            }
            Ok((levels, obj.comments))
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
