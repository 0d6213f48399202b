//! abrade: Catmull-Clark subdivision of every object of an OBJ stream (the paper's abrasion).

use anyhow::Context;
use clap::Parser;
use shared::cli;
use shared::geometry::mesh::PolyMesh;
use shared::geometry::subdiv;
use shared::text::excerpt;
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
    /// The most faces an object may have at its last level (each level multiplies them by
    /// about 4); a larger request is refused before it is made
    #[arg(long, default_value_t = 2_000_000)]
    max_faces: u64,
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
    let max_faces = args.max_faces;
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
            // Level 1 makes a quad of each face corner; each level after it 4 of each quad.
            if l1 > 0 {
                let corners = obj.mesh.face_verts.len() as u64;
                let faces = corners.saturating_mul(4u64.saturating_pow(l1 - 1));
                if faces > max_faces {
                    anyhow::bail!(
                        "object '{}' (line {}): level {l1} would have {faces} faces, more than --max-faces {max_faces}",
                        excerpt(&obj.mesh.name),
                        obj.line
                    );
                }
            }
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
