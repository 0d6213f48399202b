//! render: an OBJ stream to a shaded PNG picture, objects in a grid of labelled cells.

use clap::Parser;
use shared::cli;
use shared::draw::render::{self, Options};
use shared::geometry::obj;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7 | render --cols 5 > templates.png
  abrade --levels 0..3 < cube.obj | render --same-scale --cols 4 --title 'Cube' > cube.png

Objects are grouped into cells by the part of their name before the first '/' (a cell holds
'fig/sphere' and 'fig/plane1' together); the cell's label is that part. An object attribute
'#@ color=RRGGBB' sets its colour. Faces are drawn two-sided, so open meshes (patches) show too.";

/// Draws every object of an OBJ stream (standard input) into one PNG (standard output):
/// orthographic view, depth-tested, lit, polygon edges drawn, one labelled cell per group.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Picture size WIDTHxHEIGHT in pixels
    #[arg(long, default_value = "1200x800", value_parser = parse_size)]
    size: (u32, u32),
    /// Cells per row (default: about square cells)
    #[arg(long)]
    cols: Option<usize>,
    /// Camera azimuth, degrees (about the z axis)
    #[arg(long, default_value_t = 35.0, allow_negative_numbers = true)]
    azimuth: f64,
    /// Camera elevation, degrees above the xy plane
    #[arg(long, default_value_t = 25.0, allow_negative_numbers = true)]
    elevation: f64,
    /// Do not draw polygon edges
    #[arg(long)]
    no_edges: bool,
    /// Draw all cells at one scale, so sizes compare
    #[arg(long)]
    same_scale: bool,
    /// A title across the top
    #[arg(long)]
    title: Option<String>,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("size '{s}' is not WIDTHxHEIGHT"))?;
    let p = |v: &str| {
        v.parse::<u32>()
            .ok()
            .filter(|&n| (16..=8192).contains(&n))
            .ok_or_else(|| format!("'{v}' is not a size from 16 to 8192"))
    };
    Ok((p(w)?, p(h)?))
}

fn main() -> ExitCode {
    cli::run("render", || run(Cli::parse()))
}

fn run(args: Cli) -> anyhow::Result<()> {
    for (name, angle) in [("--azimuth", args.azimuth), ("--elevation", args.elevation)] {
        if !angle.is_finite() {
            return Err(cli::usage(format!(
                "{name} {angle}: must be a finite angle in degrees"
            )));
        }
    }
    let objects = obj::read_all(cli::stdin())?;
    cli::require_objects(objects.len() as u64)?;
    let meshes = objects.into_iter().map(|o| o.mesh).collect();
    let cells = render::group_cells(meshes);
    let opts = Options {
        width: args.size.0,
        height: args.size.1,
        cols: args.cols,
        azimuth: args.azimuth,
        elevation: args.elevation,
        edges: !args.no_edges,
        same_scale: args.same_scale,
        title: args.title,
    };
    let img = render::render(&cells, &opts);
    cli::write_png_stdout(&img)
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_well_formed() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
