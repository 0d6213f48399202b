//! triax: the drained conventional triaxial test of a pack specimen, with a flexible membrane.

use anyhow::{bail, Context};
use clap::Parser;
use shared::cli;
use shared::dem::io::state::{self, Item, StateStream};
use shared::dem::io::vtk::Snapshots;
use shared::dem::world::World;
use shared::lab::triax::{
    self, Boundary, Event, Measure, Params, Progress, Triax, TriaxError, BALANCE_WINDOW, OPENING,
    RAMP,
};
use std::io::{BufRead, Write};
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7 | abrade --levels 2 | pack --seed 1 > ab2-spec.jsonl
  triax < ab2-spec.jsonl > ab2-triax.jsonl                       (100 kPa, to 15 % axial strain)
  triax --summary ab2.json --csv ab2.csv < ab2-spec.jsonl > ab2-triax.jsonl
  triax --pressure 2e5 --rate 0.2 --final-strain 0.2 < spec.jsonl > run.jsonl
  triax --boundary rigid < spec.jsonl > rigid.jsonl      (the rigid cylinder on a servo)
  triax --stop-at 0.05 < spec.jsonl > part.jsonl && triax < part.jsonl > rest.jsonl
      (cat part.jsonl rest.jsonl: the same bytes as the run in one go)
  triax --hold 20000 --hold-every 4000 < part.jsonl > held.jsonl
      (the platens still at 5 % of strain for 20 000 steps: how q, the unbalanced ratio and,
      by fabric on the frames, the sliding ratio settle when nothing is driven)
  pipelines/triax-resume.sh spec.jsonl run.jsonl        (a killed run goes on from its last
      whole frame: a checkpoint in consolidation, every --checkpoint-every steps, or in loading)
  triax --vtk out/run-vtk --obj end.obj < spec.jsonl > run.jsonl && render < end.obj > end.png
  dem --frame last --steps 0 --obj end.obj < run.jsonl > /dev/null   (any frame is a dem state)

Standard input: a specimen made by pack in a cylinder (a dem state whose walls are the bottom
platen, the top platen and the cylinder), or a stream this tool wrote, which it resumes from
its last frame. Standard output (JSON lines, docs/formats/triax-stream.md): the settings,
checkpoints in consolidation, then a measurement every --every of axial strain and a frame (a
complete dem state after a frame record) every --frame-every, at the start of loading and at
the end. Progress goes to standard error unless --quiet: on a terminal one line redrawn in
place, in a log a line every 5 s (GRANULAR_PROGRESS_SECONDS), each line prefixed with
[GRANULAR_TAG] when that is set. Threads: RAYON_NUM_THREADS, or in a Slurm job
SLURM_CPUS_PER_TASK.

The test (docs/models/triax.md): the cylinder becomes a membrane (--membrane-young,
--membrane-poisson, --membrane-thickness; facets no larger than --membrane-edge, by default the
smallest particle) sealed to the platens, under --pressure on its outside; the platens servo to
the same pressure until the specimen is in equilibrium (isotropic consolidation); then they
approach each other at the constant logarithmic strain rate --rate, the confining pressure held,
to --final-strain. With --boundary rigid the pack's cylinder stays instead of the membrane, its
radius on a servo that holds its contacts' stress at --pressure. Strains: axial ln(H0 / H), volumetric ln(V0 / V) of the volume the membrane
and the platens enclose, compression positive; stresses in Pa, compression positive.";

/// The drained triaxial test of a pack specimen, with a flexible membrane
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Confining pressure, Pa
    #[arg(long, default_value_t = 1e5, allow_negative_numbers = true)]
    pressure: f64,
    /// The lateral boundary: membrane (the paper's flexible sleeve) or rigid (the cylinder,
    /// its radius on a servo to --pressure)
    #[arg(long, default_value = "membrane")]
    boundary: Boundary,
    /// Axial strain ln(H0 / H) at which loading ends
    #[arg(long, default_value_t = 0.15, allow_negative_numbers = true)]
    final_strain: f64,
    /// Axial strain rate, 1/s. The default is the fastest rate at which q and eps_v agree with
    /// half the rate on the paper's specimen (q within 2 % of peak q up to 5 % of strain); the
    /// sliding ratio and the rotation still depend on it (docs/models/triax.md, "Rates")
    #[arg(long, default_value_t = 0.125, allow_negative_numbers = true)]
    rate: f64,
    /// Axial strain between measurements
    #[arg(long, default_value_t = 1e-3, allow_negative_numbers = true)]
    every: f64,
    /// Measure the first --every also at --every / 2^k, k from this down to 1 (q's steep
    /// elastic start, which E50 and the initial Poisson's ratio need resolved; 0: none)
    #[arg(long, default_value_t = OPENING)]
    opening: u32,
    /// Axial strain over which the platens come up to speed at the start of loading (smoothly;
    /// 0: at once, which sends a stress wave through the specimen: docs/models/triax.md)
    #[arg(long, default_value_t = RAMP, allow_negative_numbers = true)]
    ramp: f64,
    /// Axial strain between frames (complete states)
    #[arg(long, default_value_t = 5e-3, allow_negative_numbers = true)]
    frame_every: f64,
    /// The membrane's Young's modulus, Pa
    #[arg(long, default_value_t = 7.8e6, allow_negative_numbers = true)]
    membrane_young: f64,
    /// The membrane's Poisson's ratio (rubber: nearly incompressible)
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    membrane_poisson: f64,
    /// The membrane's thickness, m
    #[arg(long, default_value_t = 2e-3, allow_negative_numbers = true)]
    membrane_thickness: f64,
    /// The membrane's largest facet edge, m [default: the smallest particle's size]; 1.5 times that ran the quick tests 1.7x as fast, their peak q and phi_p within the scatter any membrane change brings (docs/performance.md)
    #[arg(long, allow_negative_numbers = true)]
    membrane_edge: Option<f64>,
    /// Stiffness of the particles' contacts with the membrane, N/m^3: the pressure on a facet
    /// over the local penetration (a Winkler foundation) [default: the sheet's compression,
    /// --membrane-young / --membrane-thickness]
    #[arg(long, allow_negative_numbers = true)]
    membrane_stiffness: Option<f64>,
    /// Local damping of the membrane's nodes (a boundary device: its inertia is not the
    /// rubber's)
    #[arg(long, default_value_t = 0.7, allow_negative_numbers = true)]
    membrane_damping: f64,
    /// Keep the bodies' true inertia (slower: the smallest particle sets the time step); when
    /// resuming a stream, load on from its last frame with the true inertia
    #[arg(long)]
    no_inertia_scaling: bool,
    /// Time step over the critical one
    #[arg(long, default_value_t = 0.2, allow_negative_numbers = true)]
    safety: f64,
    /// Consolidation ends with both platens within this relative tolerance of --pressure
    #[arg(long, default_value_t = 0.02, allow_negative_numbers = true)]
    tolerance: f64,
    /// ... and the unbalanced-force ratio of the load-bearing bodies (two contacts or more),
    /// averaged over --balance-window steps, below this
    #[arg(long, default_value_t = 5e-3, allow_negative_numbers = true)]
    unbalanced: f64,
    /// Steps over which consolidation's unbalanced ratio is averaged (each block's mean checked
    /// at its end, with the platens)
    #[arg(long, default_value_t = BALANCE_WINDOW)]
    balance_window: u64,
    /// The particles' local damping during consolidation [default: the specimen's own]
    #[arg(long, allow_negative_numbers = true)]
    consolidation_damping: Option<f64>,
    /// The most steps consolidation may take
    #[arg(long, default_value_t = 2_000_000)]
    max_steps: u64,
    /// During consolidation, a frame every this many steps (0: none; a multiple of
    /// --balance-window), from which a run stopped in consolidation resumes (cut the stream
    /// after that frame's state)
    #[arg(long, default_value_t = 20_000)]
    checkpoint_every: u64,
    /// End the run at the first frame at or past this axial strain (resume it later from
    /// the stream)
    #[arg(long, allow_negative_numbers = true)]
    stop_at: Option<f64>,
    /// Instead of loading, hold the platens for STEPS steps from where the test is (after
    /// consolidation, or at the input stream's last frame): they slow down over the stream's
    /// --ramp of strain, as they came up to speed, and stay still, the lateral boundary at
    /// --pressure, so that the specimen relaxes with nothing driven. The stream goes on with
    /// a measurement and a frame every --hold-every steps, and loads on when resumed
    #[arg(long, value_name = "STEPS", conflicts_with = "stop_at")]
    hold: Option<u64>,
    /// Steps between a hold's measurements and frames (--hold)
    #[arg(long, value_name = "STEPS", default_value_t = 2000, requires = "hold")]
    hold_every: u64,
    /// Write the test's summary (peak q, E50, Poisson's ratio, friction and dilatancy angles,
    /// final volumetric strain) as one JSON line to FILE
    #[arg(long, value_name = "FILE")]
    summary: Option<std::path::PathBuf>,
    /// Write the measurements as CSV to FILE (for `plot`)
    #[arg(long, value_name = "FILE")]
    csv: Option<std::path::PathBuf>,
    /// Write VTK snapshots (particles, contacts, walls with the membrane) at every frame into DIR
    /// (a resumed run numbers its snapshots on from the stream's frames)
    #[arg(long, value_name = "DIR")]
    vtk: Option<std::path::PathBuf>,
    /// Write the bodies at the end as an OBJ stream to FILE, each coloured by its rotation
    /// since the start of loading (blue none, red the most), for `render`
    #[arg(long, value_name = "FILE")]
    obj: Option<std::path::PathBuf>,
    /// The group (`render` cell) of the --obj objects
    #[arg(long, default_value = "triax")]
    obj_group: String,
    /// No progress on standard error
    #[arg(long)]
    quiet: bool,
}

fn main() -> ExitCode {
    cli::run("triax", || run(Cli::parse()))
}

/// The stream's first line: its format and the test's settings.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Settings {
    #[serde(rename = "type")]
    kind: String,
    format: String,
    version: u32,
    params: Params,
    /// The membrane as made: nodes, triangles, the mass of a node (kg) and the time step (s).
    nodes: usize,
    triangles: usize,
    node_mass: f64,
    dt: f64,
    particles: usize,
}

/// A measurement's record: its type first, as every record of these streams.
#[derive(serde::Serialize)]
struct MeasureRecord<'a> {
    #[serde(rename = "type")]
    kind: &'static str,
    #[serde(flatten)]
    measure: &'a Measure,
}

/// A frame's record, before its state.
#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct FrameRecord {
    #[serde(rename = "type")]
    kind: String,
    axial_strain: f64,
    step: u64,
    /// The number of records of the state that follows: a frame cut short is found.
    records: usize,
    progress: Progress,
}

/// Writes a frame: its record (at axial strain `strain`) and the state, flushed (a frame is of
/// use to resume from only once it is whole on disk).
fn write_frame(
    out: &mut impl Write,
    w: &World,
    progress: &Progress,
    strain: f64,
) -> anyhow::Result<()> {
    let f = FrameRecord {
        kind: "frame".into(),
        axial_strain: strain,
        step: w.step,
        records: state::record_count(w),
        progress: progress.clone(),
    };
    writeln!(out, "{}", serde_json::to_string(&f)?)?;
    state::write_world(w, &mut *out)?;
    out.flush()?;
    Ok(())
}

/// Consolidates `test` (new, or resumed from a frame in consolidation), writing a frame to
/// `out` every `checkpoint` steps and its progress to `progress`.
fn consolidate(
    test: &mut Triax,
    checkpoint: u64,
    out: &mut (impl Write + Send),
    progress: &cli::Progress,
) -> anyhow::Result<()> {
    let mut failure: Option<anyhow::Error> = None;
    let (clock, first) = (std::time::Instant::now(), test.world.step);
    // Steps of consolidation before this run (resumed from a checkpoint).
    let (target, before) = (test.params.unbalanced, first - test.progress.start_step);
    let window = test.params.balance_window;
    let mut report = |e: Event| {
        match e {
        Event::Consolidating(step, s, u) => progress.status(|| {
            format!(
                "consolidation step {step}: platens {:.4e} {:.4e} Pa, unbalanced {u:.3e} over the last {window} steps (ends below {target:.0e}), {:.0} steps/s",
                s[0],
                s[1],
                per_second(step - before, clock),
            )
        }),
        Event::Checkpoint(w, p) if failure.is_none() => {
            failure = write_frame(out, w, p, 0.0).err();
        }
        _ => {}
    }
    };
    test.consolidate(CONSOLIDATION_REPORT, checkpoint, &mut report)?;
    if let Some(e) = failure {
        return Err(e);
    }
    // A resumed consolidation ran only its last steps here.
    let (all, ran) = (
        test.progress.consolidation_steps.unwrap_or_default(),
        test.world.step - first,
    );
    let secs = clock.elapsed().as_secs_f64();
    let took = if ran == all {
        format!("{secs:.1} s")
    } else {
        format!("the last {ran} in {secs:.1} s")
    };
    progress.say(&format!(
        "consolidated in {all} steps ({took}); loading at {} /s to axial strain {}",
        test.params.rate, test.params.final_strain
    ));
    Ok(())
}

/// Steps of consolidation between the engine's reports (each a cheap check of the time).
const CONSOLIDATION_REPORT: u64 = 100;

/// Steps a second since `clock` started, `steps` of them run.
fn per_second(steps: u64, clock: std::time::Instant) -> f64 {
    steps as f64 / clock.elapsed().as_secs_f64().max(1e-9)
}

const FORMAT: &str = "granular-triax";
const VERSION: u32 = 1;

fn params_of(args: &Cli) -> Params {
    Params {
        pressure: args.pressure,
        boundary: args.boundary,
        final_strain: args.final_strain,
        rate: args.rate,
        young: args.membrane_young,
        poisson: args.membrane_poisson,
        thickness: args.membrane_thickness,
        edge: args.membrane_edge,
        membrane_stiffness: args.membrane_stiffness,
        membrane_damping: args.membrane_damping,
        every: args.every,
        opening: args.opening,
        ramp: args.ramp,
        frame_every: args.frame_every,
        inertia_scaling: !args.no_inertia_scaling,
        safety: args.safety,
        tolerance: args.tolerance,
        unbalanced: args.unbalanced,
        balance_window: args.balance_window,
        consolidation_damping: args.consolidation_damping,
        max_steps: args.max_steps,
        ..Params::default()
    }
}

/// A triax error as the user of this tool meets it: a parameter by its option's name.
fn flagged(e: TriaxError) -> anyhow::Error {
    match e {
        TriaxError::Param { field, rule } => {
            let flag = match field {
                "young" | "poisson" | "thickness" | "edge" => format!("membrane-{field}"),
                "membrane_stiffness" => "membrane-stiffness".into(),
                "membrane_damping" => "membrane-damping".into(),
                f => f.replace('_', "-"),
            };
            cli::usage(format!("--{flag} {rule}"))
        }
        e => e.into(),
    }
}

/// What the input is: a specimen to test, or a stream to resume.
enum Input {
    Specimen(World),
    Resume {
        params: Params,
        world: World,
        progress: Progress,
        /// The measurements before the frame resumed from, and the first frame's orientations.
        series: Vec<Measure>,
        start: Option<Vec<nalgebra::UnitQuaternion<f64>>>,
        /// The times of the loading frames so far (each a VTK snapshot, with --vtk).
        frames: Vec<f64>,
    },
}

/// Reads standard input: a pack specimen (a dem state) or a triax stream.
fn read_input() -> anyhow::Result<Input> {
    let mut input = cli::stdin();
    let first = loop {
        let buf = input.fill_buf().context("reading standard input")?;
        if buf.is_empty() {
            bail!("the input is empty: expected a pack specimen or a triax stream");
        }
        let line_end = buf.iter().position(|&b| b == b'\n').unwrap_or(buf.len());
        let text = String::from_utf8_lossy(&buf[..line_end]).to_string();
        if !text.trim().is_empty() {
            break text;
        }
        let skip = (line_end + 1).min(buf.len());
        input.consume(skip);
    };
    match state::record_type(&first).as_deref() {
        Some("header") => Ok(Input::Specimen(state::read_world(input)?)),
        Some("triax") => read_stream(input),
        Some(t) => bail!(
            "line 1: a '{t}' record: expected a pack specimen (a dem state) or a triax stream"
        ),
        None => bail!("line 1: not a JSON record with a \"type\""),
    }
}

/// A triax stream: its settings, its measurements and its last frame.
fn read_stream(input: impl BufRead) -> anyhow::Result<Input> {
    let mut params = None;
    let (mut series, mut pending) = (Vec::new(), Vec::new());
    let mut frame: Option<(FrameRecord, usize)> = None;
    let mut last: Option<(World, Progress)> = None;
    let mut start = None;
    let mut frames = Vec::new();
    for item in StateStream::new(input) {
        match item? {
            Item::Record(v, n) => match v.get("type").and_then(|t| t.as_str()) {
                Some("triax") => {
                    let s: Settings = serde_json::from_value(v)
                        .map_err(|e| anyhow::anyhow!("line {n}: triax settings: {e}"))?;
                    if s.format != FORMAT || s.version != VERSION {
                        bail!("line {n}: format {} version {}: this triax reads {FORMAT} version {VERSION}", s.format, s.version);
                    }
                    if params.is_some() {
                        bail!("line {n}: a second settings record");
                    }
                    params = Some(s.params);
                }
                Some("measure") => pending.push(
                    serde_json::from_value::<Measure>(v)
                        .map_err(|e| anyhow::anyhow!("line {n}: measure: {e}"))?,
                ),
                Some("frame") => {
                    let f: FrameRecord = serde_json::from_value(v)
                        .map_err(|e| anyhow::anyhow!("line {n}: frame: {e}"))?;
                    frame = Some((f, n));
                }
                Some(t) => bail!("line {n}: a '{t}' record in a triax stream"),
                None => bail!("line {n}: a record without a type"),
            },
            Item::State(w, n, records) => {
                let Some((f, _)) = frame.take() else {
                    bail!("line {n}: a state without its frame record before it");
                };
                if records != f.records {
                    bail!(
                        "line {n}: the frame's state has {records} records, not {} (truncated?)",
                        f.records
                    );
                }
                // Rotations count from the start of loading, not from a frame in consolidation.
                if f.progress.phase == "loading" {
                    if start.is_none() {
                        start = Some(w.bodies.iter().map(|b| b.rot).collect());
                    }
                    frames.push(w.time);
                }
                series.append(&mut pending);
                last = Some((*w, f.progress));
            }
        }
    }
    let Some(params) = params else {
        bail!("the triax stream has no settings record");
    };
    if let Some((_, n)) = frame {
        bail!("line {n}: the stream ends in a frame record without its state (truncated?)");
    }
    let Some((world, progress)) = last else {
        bail!("the triax stream holds no frame to resume from");
    };
    Ok(Input::Resume {
        params,
        world,
        progress,
        series,
        start,
        frames,
    })
}

/// Colour of a rotation `angle` on a scale to `top`: blue, through yellow, to red.
fn rotation_colour(angle: f64, top: f64) -> String {
    let t = if top > 0.0 {
        (angle / top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let stops = [
        (0.0, [49.0, 54.0, 149.0]),
        (0.5, [254.0, 224.0, 144.0]),
        (1.0, [165.0, 0.0, 38.0]),
    ];
    let k = if t <= 0.5 { 0 } else { 1 };
    let (a, b) = (stops[k], stops[k + 1]);
    let f = (t - a.0) / (b.0 - a.0);
    let c: Vec<String> = (0..3)
        .map(|i| format!("{:02x}", (a.1[i] + f * (b.1[i] - a.1[i])).round() as u8))
        .collect();
    c.concat()
}

/// The bodies as an OBJ stream, coloured by their rotation since `start` (on a scale to the
/// 95th percentile, so that a few spinning rattlers do not wash the picture out).
fn bodies_obj(
    world: &World,
    start: &[nalgebra::UnitQuaternion<f64>],
    group: &str,
) -> anyhow::Result<Vec<u8>> {
    let angles: Vec<f64> = (world.bodies.iter().zip(start))
        .map(|(b, s)| b.rot.angle_to(s))
        .collect();
    let mut sorted = angles.clone();
    sorted.sort_by(f64::total_cmp);
    let top = sorted
        .get((sorted.len() * 95) / 100)
        .copied()
        .unwrap_or(0.0);
    let mut out = shared::geometry::obj::ObjWriter::relative(Vec::new());
    for (id, (b, angle)) in world.bodies.iter().zip(&angles).enumerate() {
        let shape = &world.shapes[b.shape as usize];
        let mut mesh = shape.posed_mesh(&b.pos, &b.rot, b.scale);
        mesh.name = format!("{group}/{id}");
        mesh.attrs
            .0
            .push(("color".into(), rotation_colour(*angle, top)));
        out.object(&mesh, &[])?;
    }
    Ok(out.into_inner()?)
}

/// Output files are checked before the run: their folders exist.
fn run(args: Cli) -> anyhow::Result<()> {
    if args.obj_group.is_empty() || args.obj_group.contains(['/', ' ']) {
        return Err(cli::usage(format!(
            "--obj-group must be a word without spaces or '/', got '{}'",
            args.obj_group
        )));
    }
    if let Some(s) = args.stop_at {
        if !(s >= 0.0 && s.is_finite()) {
            return Err(cli::usage(format!(
                "--stop-at must be an axial strain of 0 or more, got {s}"
            )));
        }
    }
    if args.hold == Some(0) || args.hold_every == 0 {
        return Err(cli::usage(
            "--hold and --hold-every must be at least 1 step",
        ));
    }
    params_of(&args).check().map_err(flagged)?;
    for (path, flag) in [
        (&args.summary, "--summary"),
        (&args.csv, "--csv"),
        (&args.obj, "--obj"),
    ] {
        cli::check_output(path.as_deref(), flag)?;
    }
    let clock = std::time::Instant::now();
    let report = if args.quiet {
        cli::Progress::quiet("triax")
    } else {
        cli::Progress::new("triax")
    };
    let say = |msg: String| report.say(&msg);
    // Written from the pool's thread as the test goes: a handle that is `Send`.
    let mut out = std::io::BufWriter::with_capacity(1 << 20, std::io::stdout());
    let (mut test, mut series, mut start, frames) = match read_input()? {
        Input::Specimen(world) => {
            let mut test = Triax::new(world, params_of(&args)).map_err(flagged)?;
            let (nodes, triangles, node_mass) = match (
                &test.world.walls[triax::MEMBRANE].kind,
                &test.world.walls[triax::MEMBRANE].membrane,
            ) {
                (
                    shared::dem::wall::WallKind::Facets {
                        nodes, triangles, ..
                    },
                    Some(m),
                ) => (nodes.len(), triangles.len(), m.sheet.node_mass),
                _ if test.params.boundary == Boundary::Rigid => (0, 0, 0.0),
                _ => bail!("the membrane was not made"),
            };
            let settings = Settings {
                kind: "triax".into(),
                format: FORMAT.into(),
                version: VERSION,
                params: test.params.clone(),
                nodes,
                triangles,
                node_mass,
                dt: test.world.dt,
                particles: test.world.bodies.len(),
            };
            writeln!(out, "{}", serde_json::to_string(&settings)?)?;
            let boundary = if nodes == 0 {
                "the rigid cylinder on its servo".to_string()
            } else {
                format!(
                    "membrane of {nodes} nodes ({node_mass:.3e} kg each), {triangles} triangles"
                )
            };
            say(format!(
                "{} particles; {boundary}; time step {:.4e} s; consolidating at {} Pa on {}",
                test.world.bodies.len(),
                test.world.dt,
                test.params.pressure,
                cli::threads()
            ));
            consolidate(&mut test, args.checkpoint_every, &mut out, &report)?;
            (test, Vec::new(), None, Vec::new())
        }
        Input::Resume {
            params,
            world,
            progress,
            series,
            start,
            frames,
        } => {
            if !["consolidation", "loading"].contains(&progress.phase.as_str()) {
                bail!(
                    "the last frame's phase is '{}', not consolidation or loading",
                    progress.phase
                );
            }
            let mut test = Triax::resume(world, params, progress).map_err(flagged)?;
            if args.no_inertia_scaling && test.params.inertia_scaling {
                // Loading on from here with the true inertia (the rate table's comparison).
                test.params.inertia_scaling = false;
                shared::lab::inertia::restore_inertia(&mut test.world, test.params.safety);
                say(format!(
                    "true inertia from here on: time step {:.4e} s",
                    test.world.dt
                ));
            }
            if test.progress.phase == "consolidation" {
                say(format!(
                    "resuming consolidation at its step {} with the stream's settings, on {}",
                    test.world.step - test.progress.start_step,
                    cli::threads()
                ));
                consolidate(&mut test, args.checkpoint_every, &mut out, &report)?;
            } else {
                say(format!(
                    "resuming at step {} (axial strain {:.4}) with the stream's settings, on {}",
                    test.world.step,
                    (test.progress.height0 / test.measure().height).ln(),
                    cli::threads()
                ));
            }
            (test, series, start, frames)
        }
    };
    let mut snapshots = match &args.vtk {
        Some(dir) => {
            // A resumed run numbers its snapshots on from the stream's frames.
            Some(
                Snapshots::continuing(dir, &frames)
                    .with_context(|| format!("creating {}", dir.display()))?,
            )
        }
        None => None,
    };
    let loading_clock = std::time::Instant::now();
    let first_step = test.world.step;
    let (rate, dt, final_strain) = (test.params.rate, test.world.dt, test.params.final_strain);
    let end = args.stop_at.map_or(final_strain, |s| s.min(final_strain));
    let mut failure: Option<anyhow::Error> = None;
    let mut sink = |e: Event| {
        if failure.is_some() {
            return;
        }
        let r = (|| -> anyhow::Result<()> {
            match e {
                Event::Measure(m) => {
                    let record = MeasureRecord {
                        kind: "measure",
                        measure: m,
                    };
                    writeln!(out, "{}", serde_json::to_string(&record)?)?;
                    series.push(m.clone());
                }
                Event::Frame(w, progress) => {
                    let strain = series.last().map_or(0.0, |m| m.axial_strain);
                    write_frame(&mut out, w, progress, strain)?;
                    if start.is_none() {
                        start = Some(w.bodies.iter().map(|b| b.rot).collect());
                    }
                    if let Some(s) = snapshots.as_mut() {
                        s.write(w).context("writing a VTK snapshot")?;
                    }
                }
                Event::Loading(step, strain) => report.status(|| {
                    let speed = per_second(test_steps(step, first_step), loading_clock);
                    // The strain rate is constant past the ramp: the steps left follow.
                    let left = (end - strain).max(0.0) / (rate * dt) / speed.max(1e-9);
                    let q = series.last().map_or(String::new(), |m| {
                        format!(
                            ": q {:.4e} Pa, volumetric strain {:.4e}",
                            m.q_boundary, m.volumetric_strain
                        )
                    });
                    format!(
                        "axial strain {strain:.4} of {end} ({:.0} %){q}, {speed:.0} steps/s, about {} left",
                        100.0 * strain / end,
                        cli::duration(left)
                    )
                }),
                Event::Holding(held, steps) => report.status(|| {
                    let speed = per_second(held, loading_clock);
                    let q = series.last().map_or(String::new(), |m| {
                        format!(
                            ": q {:.4e} Pa, unbalanced {:.3e}",
                            m.q_boundary, m.unbalanced
                        )
                    });
                    format!(
                        "held {held} of {steps} steps{q}, {speed:.0} steps/s, about {} left",
                        cli::duration((steps - held) as f64 / speed.max(1e-9))
                    )
                }),
                Event::Consolidating(..) | Event::Checkpoint(..) => {}
            }
            Ok(())
        })();
        if let Err(e) = r {
            failure = Some(e);
        }
    };
    if let Some(steps) = args.hold {
        test.relax(steps, args.hold_every, &mut sink)?;
    } else if test.progress.frames > 0 && test_is_done(&test) {
        say("the stream's test is complete: nothing to do".into());
    } else {
        test.load(args.stop_at, &mut sink)?;
    }
    report.finish();
    if let Some(e) = failure {
        return Err(e);
    }
    out.flush()?;
    if let Some(path) = &args.csv {
        let schedule = triax::Schedule::of(&test.params);
        let mut w =
            csv::Writer::from_path(path).with_context(|| format!("writing {}", path.display()))?;
        for m in &series {
            w.serialize(CsvRow::of(m, &schedule))?;
        }
        w.flush()?;
    }
    if let Some(path) = &args.obj {
        let start = start.unwrap_or_else(|| test.world.bodies.iter().map(|b| b.rot).collect());
        std::fs::write(path, bodies_obj(&test.world, &start, &args.obj_group)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let t = test.world.times;
    let share = |x: f64| 100.0 * x / t.total().max(1e-12);
    say(format!(
        "step time {:.1} s: broad phase {:.1} %, narrow phase (body pairs, walls and membrane beside) {:.1} %, forces, motion, contact list and membrane {:.1} %",
        t.total(),
        share(t.broad),
        share(t.narrow),
        share(t.integration)
    ));
    let summary = triax::summarize(&series);
    if let Some(s) = &summary {
        say(format!(
            "peak q {:.4e} Pa at axial strain {:.4}; E50 {:.4e} Pa; Poisson's ratio {:.3}; friction angle {:.2} deg; dilatancy angle {:.2} deg; over the section V/H, less the lateral boundary's stress: peak q {:.4e} Pa, friction angle {:.2} deg; final volumetric strain {:.4e}; {} steps of loading; {:.1} s",
            s.peak_q, s.peak_strain, s.e50, s.poisson_ratio, s.friction_angle, s.dilatancy_angle,
            s.peak_q_section, s.friction_angle_section, s.final_volumetric_strain, test_steps(test.world.step, test.progress.start_step), clock.elapsed().as_secs_f64()
        ));
    }
    if let Some(path) = &args.summary {
        let mut line = match &summary {
            Some(s) => serde_json::to_value(s)?,
            None => serde_json::json!({}),
        };
        line["particles"] = serde_json::json!(test.world.bodies.len());
        let loading = test_steps(test.world.step, test.progress.start_step);
        line["loading_steps"] = serde_json::json!(loading);
        if let Some(c) = test.progress.consolidation_steps {
            line["consolidation_steps"] = serde_json::json!(c);
            line["steps"] = serde_json::json!(c + loading);
        }
        line["dt"] = serde_json::json!(test.world.dt);
        line["wall_clock"] = serde_json::json!(clock.elapsed().as_secs_f64());
        line["params"] = serde_json::to_value(&test.params)?;
        std::fs::write(path, format!("{line}\n"))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Steps since loading (re)started.
fn test_steps(step: u64, first: u64) -> u64 {
    step.saturating_sub(first)
}

/// Whether the test's last frame is its final one (the final strain reached).
fn test_is_done(test: &Triax) -> bool {
    let m = test.measure();
    (test.progress.height0 / m.height).ln() >= test.params.final_strain
}

/// A measurement as a CSV row (the stress tensor's components as columns).
#[derive(serde::Serialize)]
struct CsvRow {
    step: u64,
    time: f64,
    axial_strain: f64,
    /// The axial strain the measurement was due at (a multiple of --every): the x of runs
    /// averaged together.
    nominal_strain: f64,
    volumetric_strain: f64,
    height: f64,
    volume: f64,
    sigma1: f64,
    sigma3: f64,
    q_boundary: f64,
    p_boundary: f64,
    ratio_boundary: f64,
    sxx: f64,
    syy: f64,
    szz: f64,
    sxy: f64,
    sxz: f64,
    syz: f64,
    p: f64,
    q: f64,
    ratio: f64,
    p_pairs: f64,
    membrane_stress: f64,
    q_section: f64,
    coordination: f64,
    mechanical_coordination: f64,
    radius_mean: f64,
    radius_max: f64,
    inertial: f64,
    inertial_max: f64,
    unbalanced: f64,
    contacts: usize,
}

impl CsvRow {
    fn of(m: &Measure, schedule: &triax::Schedule) -> CsvRow {
        let [sxx, syy, szz, sxy, sxz, syz] = m.stress;
        CsvRow {
            step: m.step,
            time: m.time,
            axial_strain: m.axial_strain,
            nominal_strain: schedule.nominal(m.axial_strain),
            volumetric_strain: m.volumetric_strain,
            height: m.height,
            volume: m.volume,
            sigma1: m.sigma1,
            sigma3: m.sigma3,
            q_boundary: m.q_boundary,
            p_boundary: m.p_boundary,
            ratio_boundary: m.ratio_boundary,
            sxx,
            syy,
            szz,
            sxy,
            sxz,
            syz,
            p: m.p,
            q: m.q,
            ratio: m.ratio,
            p_pairs: m.p_pairs,
            membrane_stress: m.membrane_stress,
            q_section: m.q_section,
            coordination: m.coordination,
            mechanical_coordination: m.mechanical_coordination,
            radius_mean: m.radius_mean,
            radius_max: m.radius_max,
            inertial: m.inertial,
            inertial_max: m.inertial_max,
            unbalanced: m.unbalanced,
            contacts: m.contacts,
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_well_formed() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
