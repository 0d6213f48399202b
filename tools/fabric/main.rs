//! fabric: the contact network's statistics and anisotropy, one row per dem state of a stream.

use anyhow::{bail, Context};
use clap::Parser;
use serde::Serialize;
use shared::cli;
use shared::dem::io::state::{Item, StateStream};
use shared::dem::world::World;
use shared::geometry::obj::ObjWriter;
use shared::lab::triax::Measure;
use shared::math::Mat3;
use shared::micro::fabric::{deviator, samples, Fabric, FabricError};
use shared::micro::rose::Rose;
use shared::micro::rotation::Rotations;
use shared::micro::stress::{contact_stress, coordination, invariants, sliding};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  triax < ab2-spec.jsonl | fabric > ab2-fabric.csv
  fabric --roses ab2-roses.csv --rose-obj ab2-roses.obj --group Ab_2 < ab2-triax.jsonl > ab2.csv
  render --cols 3 < ab2-roses.obj > ab2-roses.png          (the roses as shaded surfaces)
  fabric --json < ab2-triax.jsonl > ab2-fabric.jsonl          (with the tensors)
  pack --seed 1 < group.obj | fabric --volume 5.3e-3 > spec-fabric.csv

Standard input: any stream of dem states (docs/formats/dem-state.md): a triax stream (its
frames of loading, not its checkpoints in consolidation; the measurement at each frame gives the
axial strain, the specimen's volume and the boundary's stress ratio), a pack specimen or a dem
run. Standard output: one row per state, CSV
with a header (or JSON lines with --json); docs/formats/fabric.md lists the columns. The
fabric follows the paper's Eqs. 10-20 with the conventions of docs/models/fabric.md. Every state
must hold the same bodies as the first (rotations are measured from the first).";

/// The contact network's statistics and anisotropy (the paper's Eqs. 10-20), one row per dem
/// state of a stream
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Write JSON lines (with the anisotropy tensors) instead of CSV
    #[arg(long)]
    json: bool,
    /// The specimen's volume, m^3, for the absolute stresses where the stream has no triax
    /// measurements (the ratios need no volume)
    #[arg(long, allow_negative_numbers = true)]
    volume: Option<f64>,
    /// Write the roses of the normal force (start, peak q, end) as CSV to FILE: the mean
    /// normal force per direction bin
    #[arg(long, value_name = "FILE")]
    roses: Option<PathBuf>,
    /// Write the same roses as closed surfaces (an OBJ stream, radius = mean normal force in
    /// N) to FILE, for `render`
    #[arg(long, value_name = "FILE")]
    rose_obj: Option<PathBuf>,
    /// The roses' bands of equal area in z (the sectors in azimuth are twice as many)
    #[arg(long, default_value_t = 8)]
    rose_bands: usize,
    /// The group (`render` cell prefix) of the --rose-obj objects
    #[arg(long, default_value = "fabric")]
    group: String,
    /// No progress on standard error
    #[arg(long)]
    quiet: bool,
}

fn main() -> ExitCode {
    cli::run("fabric", || run(Cli::parse()))
}

/// One state's row. Quantities that a state cannot give (no contacts, no volume, no
/// boundary) are empty in CSV and null in JSON.
#[derive(Serialize, Clone, Debug, Default)]
struct Row {
    /// The state's index in the stream, from 0.
    state: usize,
    /// The line of the state's header.
    line: usize,
    step: u64,
    time: f64,
    axial_strain: Option<f64>,
    particles: usize,
    contacts: usize,
    wall_contacts: usize,
    coordination: f64,
    mechanical_coordination: f64,
    sliding_ratio: Option<f64>,
    rotation: Option<f64>,
    rotation_accumulated: Option<f64>,
    a_c: Option<f64>,
    a_bn: Option<f64>,
    a_bt: Option<f64>,
    a_fn: Option<f64>,
    a_ft: Option<f64>,
    f0: Option<f64>,
    b0: Option<f64>,
    ratio_anisotropy: Option<f64>,
    ratio_contacts: Option<f64>,
    ratio_contacts_walls: Option<f64>,
    ratio_boundary: Option<f64>,
    volume: Option<f64>,
    p_contacts: Option<f64>,
    q_contacts: Option<f64>,
    p_fabric: Option<f64>,
    q_boundary: Option<f64>,
}

/// A JSON row: the row and the anisotropy tensors (row-major 3x3).
#[derive(Serialize)]
struct JsonRow<'a> {
    #[serde(flatten)]
    row: &'a Row,
    tensors: Option<Tensors>,
}

#[derive(Serialize)]
struct Tensors {
    phi_c: [f64; 9],
    a_c: [f64; 9],
    a_bn: [f64; 9],
    a_bt: [f64; 9],
    a_fn: [f64; 9],
    a_ft: [f64; 9],
}

fn flat(m: &Mat3) -> [f64; 9] {
    let mut out = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            out[3 * r + c] = m[(r, c)];
        }
    }
    out
}

/// The bodies every state must share with the first: each body's shape and scale.
fn identity(w: &World) -> Vec<(u32, f64)> {
    w.bodies.iter().map(|b| (b.shape, b.scale)).collect()
}

/// A rose kept for the end, with the row it belongs to.
struct Kept {
    label: &'static str,
    rose: Rose,
    row: Row,
}

fn run(args: Cli) -> anyhow::Result<()> {
    if let Some(v) = args.volume {
        if !(v.is_finite() && v > 0.0) {
            return Err(cli::usage(format!(
                "--volume {v}: must be positive and finite"
            )));
        }
    }
    if args.rose_bands == 0 || args.rose_bands > 1000 {
        return Err(cli::usage(format!(
            "--rose-bands {}: must be 1 to 1000",
            args.rose_bands
        )));
    }
    // The outputs are opened first: a bad path fails before the work.
    let mut roses_csv = match &args.roses {
        Some(p) => {
            Some(csv::Writer::from_path(p).with_context(|| format!("creating {}", p.display()))?)
        }
        None => None,
    };
    let mut rose_obj = match &args.rose_obj {
        Some(p) => Some(ObjWriter::relative(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        ))),
        None => None,
    };
    let out = cli::stdout();
    let mut table = if args.json {
        Table::Json(out)
    } else {
        Table::Csv(Box::new(csv::Writer::from_writer(out)))
    };
    let result = rows(&args, &mut table);
    let kept = match result {
        Ok(kept) => kept,
        Err(e) => {
            // The rows of the good states before the error stay written.
            table.flush()?;
            return Err(e);
        }
    };
    table.flush()?;
    if let Some(w) = roses_csv.as_mut() {
        for k in &kept {
            for bin in 0..k.rose.sum.len() {
                let d = k.rose.direction(bin);
                w.serialize(RoseRow {
                    rose: k.label,
                    state: k.row.state,
                    axial_strain: k.row.axial_strain,
                    bin,
                    x: d.x,
                    y: d.y,
                    z: d.z,
                    contacts: k.rose.count[bin],
                    mean_force: k.rose.mean(bin),
                })?;
            }
        }
        w.flush()?;
    }
    if let Some(w) = rose_obj.as_mut() {
        w.comment(&cli::provenance("fabric"))?;
        for k in &kept {
            let strain = k
                .row
                .axial_strain
                .map(|e| format!(" at {:.1} %", 100.0 * e))
                .unwrap_or_default();
            let name = format!(
                "{} {}{strain}, mean {:.0} N/rose",
                args.group,
                k.label,
                k.rose.overall_mean()
            );
            let mut mesh = k.rose.mesh(&name, 1.0);
            mesh.attrs.set("color", "c8553d");
            w.object(&mesh, &[])?;
        }
    }
    if let Some(w) = rose_obj {
        w.into_inner()?.flush()?;
    }
    Ok(())
}

#[derive(Serialize)]
struct RoseRow {
    rose: &'static str,
    state: usize,
    axial_strain: Option<f64>,
    bin: usize,
    x: f64,
    y: f64,
    z: f64,
    contacts: u64,
    mean_force: f64,
}

enum Table {
    Csv(Box<csv::Writer<std::io::BufWriter<std::io::StdoutLock<'static>>>>),
    Json(std::io::BufWriter<std::io::StdoutLock<'static>>),
}

impl Table {
    fn write(&mut self, row: &Row, fabric: Option<&Fabric>) -> anyhow::Result<()> {
        match self {
            Table::Csv(w) => w.serialize(row)?,
            Table::Json(w) => {
                let tensors = fabric.map(|f| Tensors {
                    phi_c: flat(&f.phi_c),
                    a_c: flat(&f.a[0]),
                    a_bn: flat(&f.a[1]),
                    a_bt: flat(&f.a[2]),
                    a_fn: flat(&f.a[3]),
                    a_ft: flat(&f.a[4]),
                });
                serde_json::to_writer(&mut *w, &JsonRow { row, tensors })?;
                w.write_all(b"\n")?;
            }
        }
        Ok(())
    }

    fn flush(&mut self) -> anyhow::Result<()> {
        match self {
            Table::Csv(w) => w.flush()?,
            Table::Json(w) => w.flush()?,
        }
        Ok(())
    }
}

/// Reads the stream and writes a row per state; returns the roses to keep (start, peak, end).
fn rows(args: &Cli, table: &mut Table) -> anyhow::Result<Vec<Kept>> {
    let progress = cli::Progress::new("fabric");
    let mut first: Option<(Vec<(u32, f64)>, usize)> = None;
    let mut rotations: Option<Rotations> = None;
    let mut measure: Option<Measure> = None;
    // A triax frame record: the state after it must have this many records; a frame in
    // consolidation (a checkpoint to resume from) makes no row.
    let mut frame: Option<(usize, usize, bool)> = None;
    let (mut start, mut peak, mut end): (Option<Kept>, Option<(f64, Kept)>, Option<Kept>) =
        (None, None, None);
    let mut count = 0usize;
    for item in StateStream::new(cli::stdin()) {
        match item? {
            Item::Record(v, n) => match v.get("type").and_then(|t| t.as_str()) {
                Some("measure") => {
                    measure = Some(
                        serde_json::from_value(v)
                            .with_context(|| format!("line {n}: a triax measurement"))?,
                    )
                }
                Some("frame") => {
                    let records = v
                        .get("records")
                        .and_then(|r| r.as_u64())
                        .with_context(|| format!("line {n}: a frame record without 'records'"))?;
                    let consolidation = v
                        .pointer("/progress/phase")
                        .is_some_and(|p| p == "consolidation");
                    frame = Some((records as usize, n, consolidation));
                }
                _ => {}
            },
            Item::State(world, line, records) => {
                if let Some((expected, n, consolidation)) = frame.take() {
                    if records != expected {
                        bail!(
                            "line {line}: the state of the frame at line {n} has {records} records, not {expected} (truncated?)"
                        );
                    }
                    if consolidation {
                        continue;
                    }
                }
                let ids = identity(&world);
                match &first {
                    None => first = Some((ids, line)),
                    Some((ids0, line0)) => {
                        if *ids0 != ids {
                            bail!(
                                "line {line}: the state holds other bodies than the first state (line {line0}): {} bodies against {}, or their shapes differ; fabric follows one specimen",
                                ids.len(),
                                ids0.len()
                            );
                        }
                    }
                }
                let at = measure.as_ref().filter(|m| m.step == world.step);
                let (row, fabric, rose) = state_row(
                    &world,
                    count,
                    line,
                    at,
                    args,
                    &mut rotations,
                    args.rose_bands,
                );
                let fabric = match fabric {
                    Ok(f) => Some(f),
                    Err(e) => {
                        if !args.quiet {
                            let bodies = match world.bodies.len() {
                                n if n < 2 => format!("{n} bodies; "),
                                _ => String::new(),
                            };
                            shared::note!(
                                "fabric", "state {count} (line {line}): no fabric ({bodies}{e}): its anisotropy columns are empty"
                            );
                        }
                        None
                    }
                };
                table.write(&row, fabric.as_ref())?;
                let key = at
                    .map(|m| m.sigma1 - m.sigma3)
                    .or(row.q_contacts)
                    .unwrap_or(0.0);
                let kept = |label| Kept {
                    label,
                    rose: rose.clone(),
                    row: row.clone(),
                };
                if start.is_none() {
                    start = Some(kept("start"));
                }
                if peak.as_ref().is_none_or(|(q, _)| key > *q) {
                    peak = Some((key, kept("peak")));
                }
                // The last state's rose and row are the end's: moved, not copied.
                end = Some(Kept {
                    label: "end",
                    rose,
                    row,
                });
                count += 1;
                if !args.quiet {
                    progress.tick(count as u64, None, "states");
                }
            }
        }
    }
    if !args.quiet {
        progress.finish();
    }
    if let Some((_, n, _)) = frame {
        bail!("line {n}: the stream ends in a frame record without its state (truncated?)");
    }
    if count == 0 {
        bail!("the input holds no dem state (expected a stream of dem states: a triax, pack or dem output)");
    }
    Ok([start, peak.map(|(_, k)| k), end]
        .into_iter()
        .flatten()
        .collect())
}

/// A state's row, its fabric (or why it has none) and its rose.
fn state_row(
    w: &World,
    index: usize,
    line: usize,
    measure: Option<&Measure>,
    args: &Cli,
    rotations: &mut Option<Rotations>,
    bands: usize,
) -> (Row, Result<Fabric, FabricError>, Rose) {
    let set = samples(w);
    let (z, zm) = coordination(w);
    let (pairs, slide) = sliding(w);
    let orientations: Vec<_> = w.bodies.iter().map(|b| b.rot).collect();
    let rotation = rotations
        .get_or_insert_with(|| Rotations::new(orientations.clone()))
        .advance(&orientations);
    let volume = measure.map(|m| m.volume).or(args.volume);
    // Eq. 8 without the volume: the ratios need none.
    let (full, only_pairs) = contact_stress(w, 1.0);
    let ratio = |s: &Mat3| {
        let (p, q) = invariants(s);
        (p > 0.0).then(|| q / p)
    };
    let fabric = Fabric::of(&set);
    let found = fabric.as_ref().ok();
    let s = deviator(&only_pairs);
    let scalars = found.map(|f| f.scalars(&s));
    let mut rose = Rose::new(bands, 2 * bands);
    for c in &set {
        rose.add(&c.normal, c.force.dot(&c.normal));
    }
    let (p_pairs, q_pairs) = invariants(&only_pairs);
    let row = Row {
        state: index,
        line,
        step: w.step,
        time: w.time,
        axial_strain: measure.map(|m| m.axial_strain),
        particles: w.bodies.len(),
        contacts: pairs,
        wall_contacts: w.contacts.len() - pairs,
        coordination: z,
        mechanical_coordination: zm,
        sliding_ratio: (pairs > 0).then(|| slide as f64 / pairs as f64),
        rotation: rotation.map(|r| r.net),
        rotation_accumulated: rotation.map(|r| r.accumulated),
        a_c: scalars.map(|a| a[0]),
        a_bn: scalars.map(|a| a[1]),
        a_bt: scalars.map(|a| a[2]),
        a_fn: scalars.map(|a| a[3]),
        a_ft: scalars.map(|a| a[4]),
        f0: found.map(|f| f.f0),
        b0: found.map(|f| f.b0),
        ratio_anisotropy: found.map(|f| f.ratio(&s)),
        ratio_contacts: if pairs > 0 { ratio(&only_pairs) } else { None },
        ratio_contacts_walls: if !w.contacts.is_empty() {
            ratio(&full)
        } else {
            None
        },
        ratio_boundary: measure.map(|m| 3.0 * (m.sigma1 - m.sigma3) / (m.sigma1 + 2.0 * m.sigma3)),
        volume,
        p_contacts: volume.map(|v| p_pairs / v),
        q_contacts: volume.map(|v| q_pairs / v),
        p_fabric: found.zip(volume).map(|(f, v)| f.pressure(v)),
        q_boundary: measure.map(|m| m.sigma1 - m.sigma3),
    };
    (row, fabric, rose)
}
