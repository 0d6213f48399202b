//! dem: advances any DEM scene of rigid convex polyhedra and writes the new state.

use anyhow::{bail, Context};
use clap::Parser;
use serde::Serialize;
use shared::cli;
use shared::dem::contacts::Partner;
use shared::dem::io::{state, yade};
use shared::dem::law::Material;
use shared::dem::world::World;
use std::io::Write;
use std::process::ExitCode;

const EXAMPLES: &str = "\
Examples:
  dem --steps 20000 < examples/drop.jsonl > settled.jsonl
  dem --steps 1000 < settled.jsonl | dem --steps 1000 > a.jsonl   (same bytes as --steps 2000)
  dem --import-peer pipelines/yade/scene_500.txt --steps 0 > scene500.jsonl
  polygen --faces 6..14 --seed 7 > nine.obj
  dem --import-peer pipelines/yade/scene_500.txt --templates nine.obj --steps 0 > t500.jsonl
  dem --abrade 2 --steps 0 < examples/drop.jsonl > drop-ab2.jsonl   (the same scene as Ab_2 hulls)
  dem --abrade 3 --simplify 100 --steps 0 < examples/drop.jsonl      (Ab_3 hulls cut to 100 vertices)
  dem --time 0.3 --vtk out/drop --vtk-every 20000 < examples/drop.jsonl > /dev/null
  dem --until-unbalanced 1e-3 --time 2 < examples/drop.jsonl > settled.jsonl
  dem --renumber --steps 0 < t500.jsonl > t500-sorted.jsonl   (ids along space: faster steps)
      then open out/drop/particles.pvd (and contacts.pvd, walls.pvd) in ParaView

Scene format (JSON lines, version 1, SI units; docs/formats/dem-state.md): a header, then records
  {\"type\":\"header\",\"format\":\"granular-dem\",\"version\":1,\"units\":\"SI\"}
  {\"type\":\"material\",\"density\":2600,\"kn\":1e8,\"ks\":5e7,\"friction\":0.5,\"wall_friction\":0,\"damping\":0.3}
  {\"type\":\"clock\",\"time\":0,\"step\":0,\"dt\":0,\"gravity\":[0,0,-9.81]}      (dt 0: automatic)
  {\"type\":\"shape\",\"id\":0,\"name\":\"cube\",\"vertices\":[[x,y,z],...],\"faces\":[[0,1,2,3],...]}
  {\"type\":\"wall\",\"id\":0,\"kind\":\"plane\",\"normal\":[0,0,1],\"offset\":0}
  {\"type\":\"body\",\"id\":0,\"shape\":0,\"scale\":0.02,\"pos\":[0,0,0.05],\"rot\":[1,0,0,0],\"vel\":[0,0,0]}
The state written to standard output has the same records plus contacts (with their shear
springs) and the energy accumulators: a complete restart point, bit for bit.";

/// Advances a DEM scene (standard input, or --import-peer) and writes the state to standard
/// output. Rigid convex polyhedra, linear contact law with Coulomb friction, PFC local damping.
#[derive(Parser, Debug)]
#[command(version, after_help = EXAMPLES)]
struct Cli {
    /// Number of steps to run
    #[arg(long, conflicts_with = "time")]
    steps: Option<u64>,
    /// Simulated time to run, seconds
    #[arg(long)]
    time: Option<f64>,
    /// Stop as soon as the unbalanced-force ratio (mean net force on a body over mean contact
    /// force) falls below R; --steps or --time is then the limit
    #[arg(long, value_name = "R")]
    until_unbalanced: Option<f64>,
    /// Time step, seconds (default: the scene's, or --safety x critical)
    #[arg(long, allow_negative_numbers = true)]
    dt: Option<f64>,
    /// Safety factor on the critical time step when the scene has none
    #[arg(long, default_value_t = 0.2)]
    safety: f64,
    /// Replace the scene's normal stiffness kn, N/m (the time step is then recomputed unless
    /// --dt is given): e.g. to settle a bed soft and stiffen it in stages
    #[arg(long, allow_negative_numbers = true)]
    kn: Option<f64>,
    /// Replace the scene's shear stiffness ks, N/m
    #[arg(long, allow_negative_numbers = true)]
    ks: Option<f64>,
    /// Replace the scene's local damping coefficient (0 to 1)
    #[arg(long, allow_negative_numbers = true)]
    damping: Option<f64>,
    /// Write the bodies as they are at the end to FILE as an OBJ stream, one object per body
    /// (named GROUP/ID, coloured by shape), for `render`: e.g. `dem --steps 0 --obj spec.obj
    /// < spec.jsonl && render < spec.obj > spec.png`. Face indices are relative (negative), so
    /// such files concatenate into one stream
    #[arg(long, value_name = "FILE")]
    obj: Option<std::path::PathBuf>,
    /// The group (`render` cell) of the --obj objects
    #[arg(long, default_value = "specimen")]
    obj_group: String,
    /// Write a time series (energy audit, contact count, wall forces) as JSON lines to FILE
    #[arg(long)]
    series: Option<std::path::PathBuf>,
    /// Steps between time-series lines
    #[arg(long, default_value_t = 100)]
    every: u64,
    /// Write VTK snapshots (particles, contacts, walls as .vtu, and .pvd collections for
    /// ParaView) into DIR: one at the start, then every --vtk-every steps and at the end
    #[arg(long)]
    vtk: Option<std::path::PathBuf>,
    /// Steps between VTK snapshots
    #[arg(long, default_value_t = 10_000)]
    vtk_every: u64,
    /// Read a peer-scene v1 file (Yade benchmark format) instead of standard input
    #[arg(long)]
    import_peer: Option<std::path::PathBuf>,
    /// With --import-peer: a settled state (id x y z qw qx qy qz) to start from
    #[arg(long, requires = "import_peer")]
    peer_state: Option<std::path::PathBuf>,
    /// With --import-peer: an OBJ stream of T templates (e.g. `polygen --faces 6..14 --seed 7`);
    /// particle i becomes template i mod T at the particle's equivalent-sphere diameter, centroid
    /// and principal axes, so the bodies share T shapes (the benchmark's nine-template scenes)
    #[arg(long, value_name = "OBJ", requires = "import_peer")]
    templates: Option<std::path::PathBuf>,
    /// Abrade every shape LEVELS times before running (Catmull-Clark, then the convex hull: the
    /// paper's Ab_LEVELS of the scene's shapes); bodies stay where they were and only shrink,
    /// contacts are found afresh, the energy audit restarts and the time step is recomputed
    #[arg(long, value_name = "LEVELS", default_value_t = 0,
          value_parser = clap::value_parser!(u32).range(0..=4))]
    abrade: u32,
    /// Cut every shape of more than N vertices to N (after --abrade): the hull of N of its
    /// vertices (the `simplify` tool's choice), inside it; bodies stay in place as with --abrade
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(4..))]
    simplify: Option<u32>,
    /// Read the state numbered N (from 1), or the last, of a stream of states with other
    /// records between them (a `triax` stream), instead of a single state
    #[arg(long, value_name = "N|last", conflicts_with = "import_peer")]
    frame: Option<String>,
    /// Renumber the bodies along a space-filling (Morton) curve through their centroids before
    /// running, contacts and all: neighbours in space get nearby ids, which makes a step faster
    /// (the 2000-particle bed: 1.05-1.09x on 1 thread, 1.11-1.13x on 2). The state written has
    /// the new ids; the scene is the same
    #[arg(long)]
    renumber: bool,
}

#[derive(Serialize)]
struct SeriesLine {
    step: u64,
    time: f64,
    kinetic: f64,
    elastic: f64,
    friction: f64,
    damping: f64,
    gravity_work: f64,
    wall_work: f64,
    balance: f64,
    contacts: usize,
    /// null while nothing touches
    unbalanced: f64,
    wall_forces: Vec<[f64; 3]>,
}

fn series_line(w: &World) -> SeriesLine {
    let e = w.energy;
    SeriesLine {
        step: w.step,
        time: w.time,
        kinetic: e.kinetic,
        elastic: e.elastic,
        friction: e.friction,
        damping: e.damping,
        gravity_work: e.gravity_work,
        wall_work: e.wall_work,
        balance: e.balance(),
        contacts: w.contacts.len(),
        unbalanced: w.unbalanced,
        wall_forces: w
            .walls
            .iter()
            .map(|x| [x.force.x, x.force.y, x.force.z])
            .collect(),
    }
}

/// The templates of `--templates`: every object of an OBJ stream, as the shape of its hull.
fn read_templates(
    path: &std::path::Path,
    input: impl std::io::BufRead,
) -> anyhow::Result<Vec<shared::dem::shape::Shape>> {
    let objects = shared::geometry::obj::read_all(input)
        .with_context(|| format!("reading {}", path.display()))?;
    if objects.is_empty() {
        bail!(
            "{}: no objects (expected an OBJ stream of templates)",
            path.display()
        );
    }
    objects
        .iter()
        .map(|o| {
            // A closed, outward mesh first (its hull would hide an open or inside-out one).
            cli::solid(o).with_context(|| path.display().to_string())?;
            shared::dem::shape::Shape::from_mesh(&o.mesh)
                .map_err(|e| anyhow::anyhow!("{}: object at line {}: {e}", path.display(), o.line))
        })
        .collect()
}

fn main() -> ExitCode {
    cli::run("dem", || run(Cli::parse()))
}

/// State `which` (a number from 1, or `last`) of the stream of states on standard input.
/// The most steps `--time` may ask for: beyond it a run would not end on any machine.
const MAX_STEPS: f64 = 1e12;

fn read_frame(which: &str) -> anyhow::Result<World> {
    let wanted = match which {
        "last" => None,
        n => match n.parse::<usize>() {
            Ok(k) if k >= 1 => Some(k),
            _ => {
                return Err(cli::usage(format!(
                    "--frame must be a number from 1 or 'last', got '{n}'"
                )))
            }
        },
    };
    let (mut seen, mut last) = (0, None);
    for item in state::StateStream::new(cli::stdin()) {
        if let state::Item::State(w, _, _) = item? {
            seen += 1;
            if Some(seen) == wanted {
                return Ok(*w);
            }
            last = Some(w);
        }
    }
    match (wanted, last) {
        (None, Some(w)) => Ok(*w),
        (None, None) => bail!("the input holds no state"),
        (Some(k), _) => bail!("the input holds {seen} states, not {k}"),
    }
}

/// A contact deeper than this share of its smaller body's bounding radius, after the first
/// step, is warned of: far outside the linear contact law's range.
const DEEP_OVERLAP: f64 = 0.2;

fn warn_of_deep_overlap(world: &World) {
    if let Some(((partner, b), share)) = world.deepest_overlap() {
        if share > DEEP_OVERLAP {
            let with = match partner {
                Partner::Body(a) => format!("bodies {a} and {b} overlap"),
                Partner::Wall(w) => format!("body {b} overlaps wall {w}"),
            };
            shared::note!(
                "dem", "warning: {with} by {share:.3} of the smaller's bounding radius after the first step \
                 (more than {DEEP_OVERLAP}): bodies placed inside each other are flung apart; place them apart, \
                 as pack does"
            );
        }
    }
}

fn run(args: Cli) -> anyhow::Result<()> {
    cli::check_output(args.obj.as_deref(), "--obj")?;
    cli::check_output(args.series.as_deref(), "--series")?;
    let mut world = match &args.import_peer {
        Some(path) => {
            let open = |p: &std::path::Path| -> anyhow::Result<std::io::BufReader<std::fs::File>> {
                Ok(std::io::BufReader::new(
                    std::fs::File::open(p).with_context(|| format!("opening {}", p.display()))?,
                ))
            };
            let settled = args.peer_state.as_deref().map(open).transpose()?;
            let templates = match &args.templates {
                Some(p) => Some(read_templates(p, open(p)?)?),
                None => None,
            };
            yade::read_peer_scene(open(path)?, settled, templates.as_deref())
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
        }
        None => match &args.frame {
            None => state::read_world(cli::stdin())?,
            Some(which) => read_frame(which)?,
        },
    };
    if world.bodies.is_empty() {
        bail!("the scene has no bodies");
    }
    if args.abrade > 0 {
        world
            .abrade(args.abrade)
            .map_err(|e| anyhow::anyhow!("--abrade: {e}"))?;
        world.dt = 0.0; // smaller bodies: the scene's step may be above their critical one
    }
    if let Some(n) = args.simplify {
        world
            .simplify(n as usize)
            .map_err(|e| anyhow::anyhow!("--simplify: {e}"))?;
        world.dt = 0.0;
    }
    if args.renumber {
        world.renumber_along_space();
    }
    // The scene's material with the options' changes, checked as a whole.
    let m = world.material;
    let wanted = Material {
        kn: args.kn.unwrap_or(m.kn),
        ks: args.ks.unwrap_or(m.ks),
        damping: args.damping.unwrap_or(m.damping),
        ..m
    };
    wanted.check().map_err(|e| cli::usage(format!("--{e}")))?;
    if args.kn.is_some() || args.ks.is_some() {
        world.set_stiffness(wanted.kn, wanted.ks);
        world.dt = 0.0; // the scene's step was for the old stiffness
    }
    world.material.damping = wanted.damping;
    if let Some(dt) = args.dt {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(cli::usage(format!(
                "--dt must be a positive number of seconds, got {dt}"
            )));
        }
        world.dt = dt;
    }
    if world.dt == 0.0 {
        if !(args.safety > 0.0 && args.safety <= 1.0) {
            return Err(cli::usage(format!(
                "--safety must be in (0, 1], got {}",
                args.safety
            )));
        }
        let critical = world.critical_dt();
        world.dt = world.time_step(args.safety)?;
        shared::note!(
            "dem",
            "time step {:.4e} s = {} x critical {:.4e} s",
            world.dt,
            args.safety,
            critical
        );
    }
    let critical = world.critical_dt();
    if world.dt > critical {
        shared::note!(
            "dem", "warning: the time step {:.4e} s is above the critical {critical:.4e} s: the run is unstable",
            world.dt
        );
    }
    let steps = match (args.steps, args.time) {
        (Some(n), _) => n,
        (None, Some(t)) if t >= 0.0 && t.is_finite() => {
            let n = (t / world.dt).ceil();
            if n > MAX_STEPS {
                return Err(cli::usage(format!("--time {t} s at a time step of {:.4e} s is {n:.3e} steps, more than {MAX_STEPS:e}", world.dt)));
            }
            n as u64
        }
        (None, Some(t)) => {
            return Err(cli::usage(format!(
                "--time must be a non-negative number of seconds, got {t}"
            )))
        }
        (None, None) => return Err(cli::usage("say how far to run: --steps N or --time T")),
    };
    if args.every == 0 {
        return Err(cli::usage("--every must be at least 1"));
    }
    if let Some(r) = args.until_unbalanced {
        if !(r > 0.0 && r.is_finite()) {
            return Err(cli::usage(format!(
                "--until-unbalanced must be a positive ratio, got {r}"
            )));
        }
    }
    let mut series = match &args.series {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?,
        )),
        None => None,
    };
    if args.obj_group.is_empty()
        || args
            .obj_group
            .contains(|c: char| c.is_whitespace() || c == '/')
    {
        return Err(cli::usage(format!(
            "--obj-group must be a word without spaces or '/', got '{}'",
            args.obj_group
        )));
    }
    if args.vtk_every == 0 {
        return Err(cli::usage("--vtk-every must be at least 1"));
    }
    let mut snapshots = match &args.vtk {
        Some(dir) => {
            let mut s = shared::dem::io::vtk::Snapshots::new(dir)
                .with_context(|| format!("creating {}", dir.display()))?;
            s.write(&world)
                .with_context(|| format!("writing VTK into {}", dir.display()))?;
            Some(s)
        }
        None => None,
    };
    let progress = cli::Progress::new("dem");
    let start = std::time::Instant::now();
    let mut ran = 0;
    // The steps run on the pool (see `on_pool`).
    shared::dem::parallel::on_pool(|| -> anyhow::Result<()> {
        for k in 0..steps {
            world.step();
            ran = k + 1;
            if let Some(r) = world.runaway() {
                bail!(
                    "the run blew up at step {} (time {:.6e} s): {r}; no state written",
                    world.step,
                    world.time
                );
            }
            if k == 0 {
                warn_of_deep_overlap(&world);
            }
            let done = args.until_unbalanced.is_some_and(|r| world.unbalanced < r);
            let last = done || k + 1 == steps;
            if let Some(s) = series.as_mut() {
                if (k + 1) % args.every == 0 || last {
                    serde_json::to_writer(&mut *s, &series_line(&world))?;
                    s.write_all(b"\n")?;
                }
            }
            if let Some(s) = snapshots.as_mut() {
                if (k + 1) % args.vtk_every == 0 || last {
                    s.write(&world).context("writing a VTK snapshot")?;
                }
            }
            progress.tick(k + 1, Some(steps), "steps");
            if done {
                break;
            }
        }
        Ok(())
    })?;
    if let Some(r) = args.until_unbalanced {
        let ratio = world.unbalanced;
        if ratio < r {
            shared::note!(
                "dem",
                "unbalanced-force ratio {ratio:.3e} < {r} after {ran} steps"
            );
        } else {
            shared::note!("dem", "warning: unbalanced-force ratio still {ratio:.3e} (>= {r}) after the limit of {ran} steps");
        }
    }
    let steps = ran;
    progress.finish();
    if let Some(mut s) = series {
        s.flush()?;
    }
    if steps > 0 {
        let secs = start.elapsed().as_secs_f64();
        // Contacts per particle as the peer benchmark counts them: (2 N_pp + N_pw) / N.
        let ends: usize = world
            .contacts
            .keys()
            .map(|(partner, _)| match partner {
                Partner::Body(_) => 2,
                Partner::Wall(_) => 1,
            })
            .sum();
        shared::note!(
            "dem", "{steps} steps of {} bodies on {} in {secs:.2} s ({:.3e} particle-steps/s), {} contacts at the end ({:.2} per particle)",
            world.bodies.len(),
            cli::threads(),
            steps as f64 * world.bodies.len() as f64 / secs.max(1e-9),
            world.contacts.len(),
            ends as f64 / world.bodies.len() as f64
        );
        let t = world.times;
        let share = |x: f64| 100.0 * x / t.total().max(1e-300);
        shared::note!(
            "dem", "step time {:.2} s: broad phase {:.1} %, narrow phase (body pairs, walls beside) {:.1} %, forces, motion and contact list {:.1} %",
            t.total(),
            share(t.broad),
            share(t.narrow),
            share(t.integration)
        );
        shared::note!(
            "dem",
            "broad phase swept {} times in {} steps (its kept list served the others)",
            world.broad_sweeps(),
            steps
        );
        if let Some(kib) = peak_resident_kib() {
            shared::note!(
                "dem",
                "peak resident memory {:.1} MiB ({:.1} KiB per particle, all included)",
                kib as f64 / 1024.0,
                kib as f64 / world.bodies.len() as f64
            );
        }
    }
    if let Some(path) = &args.obj {
        std::fs::write(path, bodies_obj(&world, &args.obj_group)?)
            .with_context(|| format!("writing {}", path.display()))?;
    }
    let mut out = cli::stdout();
    state::write_world(&world, &mut out)?;
    out.flush()?;
    Ok(())
}

/// Colours of the shapes in `--obj`, in turn.
const PALETTE: [&str; 9] = [
    "c8553d", "588b8b", "f2c14e", "5d4e8c", "8cb369", "e07a5f", "3d5a80", "b5838d", "6d9dc5",
];

/// The bodies as an OBJ stream for `render`: object GROUP/ID per body, coloured by its shape.
fn bodies_obj(world: &shared::dem::world::World, group: &str) -> anyhow::Result<Vec<u8>> {
    let mut out = shared::geometry::obj::ObjWriter::relative(Vec::new());
    for (id, b) in world.bodies.iter().enumerate() {
        let shape = &world.shapes[b.shape as usize];
        let mut mesh = shape.posed_mesh(&b.pos, &b.rot, b.scale);
        mesh.name = format!("{group}/{id}");
        let colour = PALETTE[b.shape as usize % PALETTE.len()];
        mesh.attrs.0.push(("color".into(), colour.into()));
        out.object(&mesh, &[])?;
    }
    Ok(out.into_inner()?)
}

/// The process's peak resident set (Linux `VmHWM`), KiB; `None` where it cannot be read.
fn peak_resident_kib() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

#[cfg(test)]
mod tests {
    #[test]
    fn cli_is_well_formed() {
        use clap::CommandFactory;
        super::Cli::command().debug_assert();
    }
}
