//! pack: a dense, isotropically consolidated specimen of polyhedra, ready for the triaxial test.

use anyhow::Context;
use clap::{Parser, ValueEnum};
use shared::cli;
use shared::dem::io::state;
use shared::dem::law::Material;
use shared::dem::shape::Shape;
use shared::lab::boundary;
use shared::lab::pack::{self, Container, PackError, Params, SizeMeasure};
use std::io::Write;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  polygen --faces 6..14 --seed 7 | abrade --levels 2 | pack --seed 1 > ab2.jsonl
  polygen --faces 6..14 --seed 7 | pack --diameter 0.15 --height 0.3 --summary ip.json > ip.jsonl
  pack --count 60 --diameter 0.1 --height 0.2 --size-min 0.012 --size-max 0.02 < nine.obj > small.jsonl
  pack --relative-density 0.8 < nine.obj > dr08.jsonl     (calibrates on a half-size sample first)
  pack --limits-only --calibration-scale 1 < nine.obj > limits.json   (e_min, e_max at full size)
  pack --relative-density 0.8 --void-ratio-limits 0.618,1.175 < nine.obj > dr08.jsonl
  pack --relative-density 0.8 --void-ratio-limits 0.618,1.175 --refine-runs 1 < nine.obj > dr08.jsonl
      (the sample's friction corrected by one compaction at full size: Dr nearer 0.8)
  pack --relative-density 0.8 --journal dr08.journal < nine.obj > dr08.jsonl
      (stopped and started again, it takes the compactions it finished from dr08.journal)
  pack --container box --width 0.2 --depth 0.2 --height 0.4 < nine.obj > box.jsonl
  pack ... | dem --steps 1000 > later.jsonl      (the specimen is a dem state: it runs on)

Every object of the OBJ stream on standard input is a template; particle i is template i mod T,
so the templates come in equal numbers. The specimen goes to standard output as a dem state
(JSON lines, docs/formats/dem-state.md): bodies, contacts with their shear springs, and the walls
(all frictionless, at rest): 0 the bottom platen, 1 the top platen, then 2 the cylinder, or in
a box 2 to 5 the side planes at x-min, x-max, y-min, y-max. A summary
(count, porosity, void ratio, coordination, wall stresses, unbalanced-force ratio, contact-normal
anisotropy, largest overlap, wall-clock time) goes to standard error, and as JSON to --summary.
Progress goes to standard error: which run of how many (the limits', the calibration's, the
refinement's and the specimen's compactions), its phase, stresses and steps a second; on a
terminal one line redrawn in place, in a log a line every 5 s (GRANULAR_PROGRESS_SECONDS).

How (docs/models/pack.md): a loose cloud without contacts in the container enlarged to fit it, no
gravity; the walls close in at one strain rate (a servo with integral action on the mean stress)
at --prep-friction until the mean stress is within --tolerance of --pressure; then the particle
friction is restored and each wall holds its own servo until every wall is within --tolerance
and the unbalanced-force ratio is below --unbalanced (damping --prep-damping throughout; the
state carries --damping). --relative-density DR first finds e_min (no
friction), e_max (--loose-friction) and the preparation friction for DR on a smaller sample
(--calibration-scale). The limits depend on the container's size (a smaller one has more wall,
which loosens it): measured once at the specimen's size (--limits-only --calibration-scale 1)
and given as --void-ratio-limits, they make the reported Dr the specimen's own.
Lengths in m, stresses in Pa.";

/// The container's shape.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum Vessel {
    /// A cylinder (--diameter) between two platens
    Cylinder,
    /// A box (--width along x, --depth along y) between two platens
    Box,
}

/// What particle size means.
#[derive(Clone, Copy, Debug, ValueEnum)]
enum Measure {
    /// Diameter of the sphere of equal volume
    Equivalent,
    /// Diameter of the sphere about the centroid that holds the particle
    Circumscribed,
}

/// Turns particle templates (an OBJ stream on standard input) into a dense specimen consolidated
/// isotropically in a cylinder (or a box) between two platens; writes it as a dem state to
/// standard output.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// The container
    #[arg(long, value_enum, default_value_t = Vessel::Cylinder)]
    container: Vessel,
    /// The cylinder's diameter, m [default: 0.3]
    #[arg(long, allow_negative_numbers = true)]
    diameter: Option<f64>,
    /// The box's side along x, m [default: 0.3]
    #[arg(long, allow_negative_numbers = true)]
    width: Option<f64>,
    /// The box's side along y, m [default: 0.3]
    #[arg(long, allow_negative_numbers = true)]
    depth: Option<f64>,
    /// Container height, m
    #[arg(long, default_value_t = 0.6, allow_negative_numbers = true)]
    height: f64,
    /// Smallest particle size, m
    #[arg(long, default_value_t = 0.010, allow_negative_numbers = true)]
    size_min: f64,
    /// Largest particle size, m (sizes are uniform between the two)
    #[arg(long, default_value_t = 0.040, allow_negative_numbers = true)]
    size_max: f64,
    /// What a size is
    #[arg(long, value_enum, default_value_t = Measure::Equivalent)]
    size_measure: Measure,
    /// Number of particles, at least 6 (default: enough to fill the container at --porosity)
    #[arg(long)]
    count: Option<usize>,
    /// Porosity the default count is worked out for
    #[arg(long, default_value_t = 0.4, allow_negative_numbers = true)]
    porosity: f64,
    /// Isotropic consolidation stress, Pa
    #[arg(long, default_value_t = 100e3, allow_negative_numbers = true)]
    pressure: f64,
    /// Particle friction while compacting (lower: denser); default 0.1, or what
    /// --relative-density finds
    #[arg(
        long,
        allow_negative_numbers = true,
        conflicts_with = "relative_density"
    )]
    prep_friction: Option<f64>,
    /// Target relative density Dr = (e_max - e) / (e_max - e_min): finds e_min, e_max and the
    /// preparation friction for Dr on a smaller sample first (docs/models/pack.md; the paper's 0.8)
    #[arg(long, value_name = "DR", allow_negative_numbers = true)]
    relative_density: Option<f64>,
    /// The calibration sample's container over the specimen's, in each direction
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    calibration_scale: f64,
    /// Preparation friction of the loosest packing (e_max)
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    loose_friction: f64,
    /// Calibration runs after the two limits, each narrowing the friction for the target
    #[arg(long, default_value_t = 2)]
    calibration_runs: usize,
    /// Known void-ratio limits E_MIN,E_MAX of the same templates and sizes at the specimen's
    /// scale (--limits-only --calibration-scale 1 measures them): the specimen's relative
    /// density is reported against them; with --relative-density the sample still chooses the
    /// friction
    #[arg(long, value_name = "E_MIN,E_MAX", value_parser = parse_limits)]
    void_ratio_limits: Option<(f64, f64)>,
    /// With --relative-density and --void-ratio-limits: N compactions of the specimen itself
    /// that correct the sample's friction for the given limits (the specimen packs denser than
    /// the sample, by about the same void ratio at any friction: each run measures that offset
    /// and the sample's curve gives the next friction). Each costs about half a specimen
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        requires_all = ["relative_density", "void_ratio_limits"]
    )]
    refine_runs: usize,
    /// Measure the void-ratio limits alone, on the container scaled by --calibration-scale
    /// (1: the specimen's own), and write them to standard output as one JSON line instead of
    /// a specimen
    #[arg(long, conflicts_with_all = ["relative_density", "void_ratio_limits", "prep_friction"])]
    limits_only: bool,
    /// Local damping while preparing (compaction and equilibrium; the state gets --damping)
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    prep_damping: f64,
    /// The specimen's particle friction (the paper's 0.5)
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    friction: f64,
    /// The specimen's local damping, in the state written (the paper's 0.3)
    #[arg(long, default_value_t = 0.3, allow_negative_numbers = true)]
    damping: f64,
    /// Density, kg/m^3
    #[arg(long, default_value_t = 2600.0, allow_negative_numbers = true)]
    density: f64,
    /// Normal contact stiffness, N/m
    #[arg(long, default_value_t = 1e8, allow_negative_numbers = true)]
    kn: f64,
    /// Shear contact stiffness, N/m
    #[arg(long, default_value_t = 5e7, allow_negative_numbers = true)]
    ks: f64,
    /// Seed of the sizes, positions and orientations
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Time step over the critical one
    #[arg(long, default_value_t = 0.2, allow_negative_numbers = true)]
    safety: f64,
    /// Keep every particle's true mass and moments while preparing (by default they are scaled
    /// so that every particle's critical time step is the largest particle's; docs/models/pack.md)
    #[arg(long)]
    no_inertia_scaling: bool,
    /// Largest relative difference of a wall stress from --pressure at the end
    #[arg(long, default_value_t = 0.02, allow_negative_numbers = true)]
    tolerance: f64,
    /// Unbalanced-force ratio (mean net force over mean contact force) at the end
    #[arg(long, default_value_t = 1e-3, allow_negative_numbers = true)]
    unbalanced: f64,
    /// Unbalanced-force ratio that ends compaction
    #[arg(long, default_value_t = 1e-2, allow_negative_numbers = true)]
    prep_unbalanced: f64,
    /// Share of the loose cloud's container that the particles fill (their solid volume)
    #[arg(long, default_value_t = 0.2, allow_negative_numbers = true)]
    cloud_fraction: f64,
    /// Fastest strain rate of the walls, 1/s
    #[arg(long, default_value_t = 4.0, allow_negative_numbers = true)]
    max_strain_rate: f64,
    /// Fastest strain rate while the cloud is loose (fewer particle contacts than particles), 1/s
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    loose_strain_rate: f64,
    /// Servo gain (0 to 1)
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    gain: f64,
    /// Integral time of the compaction's servo, steps (0: proportional only; docs/models/pack.md)
    #[arg(long, value_name = "STEPS", default_value_t = 2000)]
    servo_integral: u64,
    /// Steps allowed in all
    #[arg(long, default_value_t = 2_000_000)]
    max_steps: u64,
    /// Flat facets of the cylinder wall
    #[arg(long, default_value_t = 128)]
    segments: u32,
    /// Write the summary as one JSON line to FILE
    #[arg(long)]
    summary: Option<std::path::PathBuf>,
    /// Keep each finished compaction of the limits, the calibration and the refinement in
    /// FILE (JSON lines, created if missing); started again with the same FILE, templates and
    /// options, pack takes those runs from it instead of running them again, and writes the same
    /// specimen to the bit. For long preparations that a job's time limit may stop
    #[arg(long, value_name = "FILE")]
    journal: Option<std::path::PathBuf>,
    /// Write VTK snapshots of the preparation (particles, contacts, walls as .vtu, and .pvd
    /// collections for ParaView) into DIR: one every --every steps, and the specimen
    #[arg(long, value_name = "DIR")]
    vtk: Option<std::path::PathBuf>,
    /// Steps between VTK snapshots (--vtk); progress goes to standard error every few
    /// seconds
    #[arg(long, default_value_t = 5000)]
    every: u64,
}

/// Steps between the engine's reports to the progress line (each a cheap look at the clock).
const REPORT_STEPS: u64 = 100;

/// The progress of a preparation that runs several compactions: which run of how many, what
/// it is for, and its steps a second.
struct Runs {
    progress: cli::Progress,
    /// The runs counted so far, and the most there will be.
    run: u32,
    total: u32,
    /// When the current run started, and its last step seen.
    clock: std::time::Instant,
    last: u64,
    /// The unbalanced-force ratio each phase ends below: compaction, equilibrium.
    targets: [f64; 2],
}

impl Runs {
    fn new(total: u32, targets: [f64; 2]) -> Runs {
        Runs {
            progress: cli::Progress::new("pack"),
            run: 0,
            total,
            clock: std::time::Instant::now(),
            last: 0,
            targets,
        }
    }

    /// A status of a run of `what` at preparation friction `f` (a new run when its steps
    /// start again).
    fn report(&mut self, what: &str, f: f64, s: &pack::Status) {
        let reused = s.phase == pack::REUSED;
        if reused || self.run == 0 || s.step < self.last {
            self.run += 1;
            self.clock = std::time::Instant::now();
        }
        self.last = s.step;
        let (run, total) = (self.run, self.total.max(self.run));
        if reused {
            // The next report, at any step, starts a run.
            self.last = u64::MAX;
            self.say(&format!(
                "run {run} of {total} ({what} at friction {f:.4}): taken from the journal, porosity {:.4}",
                s.porosity
            ));
            return;
        }
        let target = match s.phase {
            "compaction" => self.targets[0],
            _ => self.targets[1],
        };
        let speed = s.step as f64 / self.clock.elapsed().as_secs_f64().max(1e-9);
        self.progress.status(|| {
            format!(
                "run {run} of {total} ({what} at friction {f:.4}): {} step {}: wall stresses {} Pa, porosity {:.4}, unbalanced {:.3e} (ends below {target:.0e}), {speed:.0} steps/s",
                s.phase,
                s.step,
                stresses(&s.stresses),
                s.porosity,
                s.unbalanced
            )
        });
    }

    fn say(&self, msg: &str) {
        self.progress.say(msg)
    }
}

/// Wall stresses for a progress line: "1.0000e5 9.9000e4 ...".
fn stresses(s: &[f64]) -> String {
    let parts: Vec<String> = s.iter().map(|x| format!("{x:.4e}")).collect();
    parts.join(" ")
}

/// `E_MIN,E_MAX` as two numbers.
fn parse_limits(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(',')
        .ok_or_else(|| format!("expected E_MIN,E_MAX, got '{s}'"))?;
    let num = |x: &str| {
        x.trim()
            .parse::<f64>()
            .map_err(|_| format!("'{x}' is not a number"))
    };
    Ok((num(a)?, num(b)?))
}

fn main() -> ExitCode {
    cli::run("pack", || run(Cli::parse()))
}

/// The templates: every object of the stream, checked closed and outward, as its hull's shape.
fn templates() -> anyhow::Result<Vec<Shape>> {
    let objects = shared::geometry::obj::read_all(cli::stdin()).context("reading the templates")?;
    cli::require_objects(objects.len() as u64)?;
    objects
        .iter()
        .map(|o| {
            cli::solid(o)?;
            Shape::from_mesh(&o.mesh)
                .with_context(|| format!("object '{}' (line {})", o.mesh.name, o.line))
        })
        .collect()
}

/// A pack error as the user of this tool meets it: a parameter by its option's name.
fn flagged(e: PackError) -> anyhow::Error {
    match e {
        PackError::Param { field, rule } => {
            cli::usage(format!("--{} {rule}", field.replace('_', "-")))
        }
        e @ PackError::Crowded(..) => anyhow::anyhow!("{e} (lower --cloud-fraction)"),
        e @ PackError::NotSettled { .. } => anyhow::anyhow!("{e} (raise --max-steps)"),
        e => e.into(),
    }
}

/// The fewest particles a specimen may have (`--count`): with two or four, the walls servo
/// to the pressure on particles that rattle between them and never settle.
const MIN_COUNT: usize = 6;

/// The --journal file, opened for appending at its first line, so that a run that fails
/// before a compaction is done leaves no file; the text past its last whole line (a line
/// cut short by a stop) goes first.
struct JournalFile {
    path: std::path::PathBuf,
    whole: u64,
    file: Option<std::fs::File>,
}

impl Write for JournalFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.file.is_none() {
            let file = std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(&self.path)?;
            if file.metadata()?.len() > self.whole {
                file.set_len(self.whole)?;
            }
            self.file = Some(file);
        }
        self.file.as_mut().map_or(Ok(0), |f| f.write(buf))
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.as_mut().map_or(Ok(()), |f| f.flush())
    }
}

fn run(args: Cli) -> anyhow::Result<()> {
    cli::check_output(args.summary.as_deref(), "--summary")?;
    cli::check_output(args.journal.as_deref(), "--journal")?;
    if args.every == 0 {
        return Err(cli::usage("--every must be at least 1"));
    }
    let material = Material {
        density: args.density,
        kn: args.kn,
        ks: args.ks,
        friction: args.friction,
        wall_friction: 0.0,
        damping: args.damping,
    };
    material.check().map_err(|e| cli::usage(format!("--{e}")))?;
    let container = match args.container {
        Vessel::Cylinder => {
            if args.width.is_some() || args.depth.is_some() {
                return Err(cli::usage("--width and --depth are the sides of a box: add --container box, or give the cylinder's --diameter"));
            }
            Container::Cylinder
        }
        Vessel::Box => {
            if args.diameter.is_some() {
                return Err(cli::usage(
                    "--diameter is the cylinder's: a box has --width and --depth",
                ));
            }
            Container::Box
        }
    };
    if args.count.is_some_and(|n| (1..MIN_COUNT).contains(&n)) {
        return Err(cli::usage(format!(
            "--count must be at least {MIN_COUNT}: fewer particles do not hold the servo walls, \
             which chase them until --max-steps"
        )));
    }
    let params = Params {
        container,
        diameter: args.diameter.unwrap_or(0.3),
        width: args.width.unwrap_or(0.3),
        depth: args.depth.unwrap_or(0.3),
        height: args.height,
        size_min: args.size_min,
        size_max: args.size_max,
        size_measure: match args.size_measure {
            Measure::Equivalent => SizeMeasure::Equivalent,
            Measure::Circumscribed => SizeMeasure::Circumscribed,
        },
        count: args.count,
        porosity: args.porosity,
        pressure: args.pressure,
        prep_friction: args.prep_friction.unwrap_or(0.1),
        prep_damping: args.prep_damping,
        material,
        seed: args.seed,
        safety: args.safety,
        inertia_scaling: !args.no_inertia_scaling,
        tolerance: args.tolerance,
        prep_unbalanced: args.prep_unbalanced,
        unbalanced: args.unbalanced,
        cloud_fraction: args.cloud_fraction,
        max_strain_rate: args.max_strain_rate,
        loose_strain_rate: args.loose_strain_rate,
        gain: args.gain,
        integral_steps: args.servo_integral,
        max_steps: args.max_steps,
        segments: args.segments,
    };
    let shapes = templates()?;
    let clock = std::time::Instant::now();
    let mut params = params;
    let mut limits = args.void_ratio_limits;
    let total = if args.limits_only {
        2
    } else {
        match args.relative_density {
            Some(_) => {
                let refine = if limits.is_some() {
                    args.refine_runs
                } else {
                    0
                };
                3 + args.calibration_runs as u32 + refine as u32
            }
            None => 1,
        }
    };
    let mut runs = Runs::new(total, [params.prep_unbalanced, params.unbalanced]);
    if let Some((lo, hi)) = limits {
        if !(lo.is_finite() && hi.is_finite() && 0.0 < lo && lo < hi) {
            return Err(cli::usage(format!(
                "--void-ratio-limits must be 0 < E_MIN < E_MAX, got {lo},{hi}"
            )));
        }
    }
    let journal_text = match &args.journal {
        Some(path) => match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => String::new(),
            Err(e) => {
                return Err(e).with_context(|| format!("reading --journal {}", path.display()))
            }
        },
        None => String::new(),
    };
    let mut journal_file = args.journal.as_ref().map(|path| JournalFile {
        path: path.clone(),
        // A last line cut short by a stop goes, so that the next line starts afresh.
        whole: journal_text.rfind('\n').map_or(0, |i| i + 1) as u64,
        file: None,
    });
    let mut journal = pack::Journal::new(
        &journal_text,
        journal_file.as_mut().map(|f| f as &mut dyn Write),
    )
    .map_err(|e| match &args.journal {
        Some(path) => anyhow::anyhow!("--journal {}: {e}", path.display()),
        None => e.into(),
    })?;
    if args.limits_only {
        let l = pack::void_limits(
            &shapes,
            &params,
            args.calibration_scale,
            args.loose_friction,
            REPORT_STEPS,
            &mut journal,
            |f, s| runs.report("limits", f, s),
        )
        .map_err(flagged)?;
        let secs = clock.elapsed().as_secs_f64();
        runs.say(&format!(
            "void-ratio limits on {} particles (scale {}): e_min {:.4} (friction 0), e_max {:.4} (friction {}) in {secs:.1} s; --void-ratio-limits {:.4},{:.4}",
            l.particles, l.scale, l.e_min, l.e_max, l.loose_friction, l.e_min, l.e_max
        ));
        let mut line = serde_json::to_value(&l)?;
        line["wall_clock"] = serde_json::json!(secs);
        let text = format!("{line}\n");
        if let Some(path) = &args.summary {
            std::fs::write(path, &text).with_context(|| format!("writing {}", path.display()))?;
        }
        let mut out = cli::stdout();
        out.write_all(text.as_bytes())?;
        out.flush()?;
        return Ok(());
    }
    let calibration = match args.relative_density {
        Some(dr) => {
            let c = pack::calibrate(
                &shapes,
                &params,
                dr,
                args.calibration_scale,
                args.loose_friction,
                args.calibration_runs,
                REPORT_STEPS,
                &mut journal,
                |f, s| runs.report("calibration", f, s),
            )
            .map_err(flagged)?;
            runs.say(&format!(
                "calibration on {} particles: e_min {:.4} (friction 0), e_max {:.4} (friction {}), runs {:?}; preparation friction {:.4} for Dr {dr}",
                c.limits.particles, c.limits.e_min, c.limits.e_max, c.limits.loose_friction, c.runs, c.prep_friction
            ));
            params.prep_friction = c.prep_friction;
            if let Some((lo, hi)) = limits {
                runs.say(&format!(
                    "the specimen's Dr is reported against --void-ratio-limits {lo},{hi}, not the sample's"
                ));
            } else {
                limits = Some((c.limits.e_min, c.limits.e_max));
            }
            Some(c)
        }
        None => None,
    };
    let refinement = match (&calibration, limits) {
        (Some(c), Some(given)) if args.refine_runs > 0 => {
            let r = pack::refine(
                &shapes,
                &params,
                c,
                given,
                args.refine_runs,
                REPORT_STEPS,
                &mut journal,
                |f, s| runs.report("refinement", f, s),
            )
            .map_err(flagged)?;
            runs.say(&format!(
                "refinement at full size: target e {:.4}, runs {:?}; preparation friction {:.4}",
                r.target, r.runs, r.prep_friction
            ));
            params.prep_friction = r.prep_friction;
            Some(r)
        }
        _ => None,
    };
    let mut world = pack::cloud(shapes, &params).map_err(flagged)?;
    let prep_dt = world.dt;
    let cloud = boundary::container(&world).context("the loose cloud has no container")?;
    runs.say(&format!(
        "{} particles of {} templates in a loose cloud {}; time step {:.4e} s; on {}",
        world.bodies.len(),
        world.shapes.len(),
        cloud.describe(),
        world.dt,
        cli::threads()
    ));
    let mut snapshots = match &args.vtk {
        Some(dir) => Some(
            shared::dem::io::vtk::Snapshots::new(dir)
                .with_context(|| format!("creating {}", dir.display()))?,
        ),
        None => None,
    };
    let mut vtk_error = None;
    // The engine reports every `report` steps: to the progress line, and a VTK snapshot at
    // each --every.
    let report = gcd(REPORT_STEPS, args.every);
    pack::consolidate(&mut world, &params, report, |s, w| {
        runs.report("specimen", params.prep_friction, s);
        if s.step % args.every == 0 {
            if let (Some(v), None) = (snapshots.as_mut(), &vtk_error) {
                vtk_error = v.write(w).err();
            }
        }
    })
    .map_err(flagged)?;
    if let Some(e) = vtk_error {
        return Err(e).context("writing a VTK snapshot");
    }
    if let Some(v) = snapshots.as_mut() {
        v.write(&world).context("writing a VTK snapshot")?;
    }
    let secs = clock.elapsed().as_secs_f64();
    let summary = pack::summary(&world, &params);
    let mut line = serde_json::to_value(&summary)?;
    line["wall_clock"] = serde_json::json!(secs);
    line["prep_dt"] = serde_json::json!(prep_dt);
    line["prep_friction"] = serde_json::json!(params.prep_friction);
    line["friction"] = serde_json::json!(params.material.friction);
    line["pressure"] = serde_json::json!(params.pressure);
    line["size_measure"] = serde_json::to_value(params.size_measure)?;
    if let Some((e_min, e_max)) = limits {
        line["e_min"] = serde_json::json!(e_min);
        line["e_max"] = serde_json::json!(e_max);
        let dr = (e_max - summary.void_ratio) / (e_max - e_min);
        line["relative_density"] = serde_json::json!(dr);
        runs.say(&format!(
            "relative density {dr:.3} (e_min {e_min:.4}, e_max {e_max:.4}, e {:.4})",
            summary.void_ratio
        ));
    }
    if let Some(c) = &calibration {
        line["calibration"] = serde_json::to_value(c)?;
    }
    if let Some(r) = &refinement {
        line["refinement"] = serde_json::to_value(r)?;
    }
    let specimen = boundary::container(&world).context("the specimen has no container")?;
    runs.say(&format!(
        "{} particles, {}: porosity {:.4}, void ratio {:.4}, coordination {:.3} ({:.3} without rattlers)",
        summary.particles, specimen.describe(), summary.porosity, summary.void_ratio,
        summary.coordination, summary.mechanical_coordination
    ));
    runs.say(&format!(
        "wall stresses {} Pa (largest error {:.2} %), unbalanced {:.3e}, anisotropy {:.4} (sampling alone: {:.4}), largest overlap {:.3e} of a size, {} outside; {} steps in {:.1} s",
        stresses(&summary.wall_stresses),
        100.0 * summary.stress_error, summary.unbalanced, summary.anisotropy,
        summary.anisotropy_noise.unwrap_or(f64::NAN), summary.max_overlap,
        summary.outside, summary.steps, secs
    ));
    if let Some(path) = &args.summary {
        let mut f =
            std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        serde_json::to_writer(&mut f, &line)?;
        f.write_all(b"\n")?;
    }
    // The specimen's bodies numbered along space (`dem --renumber`): the preparation draws
    // them at random places, and a run from a state whose neighbours have far-apart ids is
    // slower (the 2000-particle bed: 1.09x on 1 thread, 1.17x on 2). Only the ids change.
    world.renumber_along_space();
    let mut out = cli::stdout();
    state::write_world(&world, &mut out)?;
    out.flush()?;
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

/// The greatest common divisor of two step counts (at least 1).
fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a.max(1)
    } else {
        gcd(b, a % b)
    }
}
