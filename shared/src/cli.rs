//! What every tool shares: one way to run and exit, stream plumbing, provenance, progress.
//!
//! Exit codes: 0 success (also when the reader of our output went away: a broken pipe is not an
//! error), 1 bad data or a failed computation, 2 bad usage (clap's own code).

use crate::geometry::obj::{Item, ObjObject, ObjReader};
use rayon::prelude::*;
use std::io::{self, BufRead, BufWriter, IsTerminal, Write};
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Runs a tool's body: prints an error once as `tool: message` (with its causes) and maps it to
/// an exit code; a broken pipe ends quietly with success.
pub fn run(tool: &str, body: impl FnOnce() -> anyhow::Result<()>) -> ExitCode {
    threads_from_slurm();
    match body() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) if e.downcast_ref::<Usage>().is_some() => {
            eprintln!("{}{e}", prefix(tool));
            ExitCode::from(2)
        }
        Err(e) => {
            let mut msg = format!("{}{e}", prefix(tool));
            for cause in e.chain().skip(1) {
                msg.push_str(&format!(": {cause}"));
            }
            eprintln!("{msg}");
            ExitCode::from(1)
        }
    }
}

/// In a Slurm job given `--cpus-per-task` (`SLURM_CPUS_PER_TASK`), the tools use that many
/// threads unless `RAYON_NUM_THREADS` says otherwise (rayon alone would take every CPU the node
/// shows).
fn threads_from_slurm() {
    if std::env::var_os("RAYON_NUM_THREADS").is_some() {
        return;
    }
    let cpus = std::env::var("SLURM_CPUS_PER_TASK").ok();
    if let Some(n) = cpus
        .and_then(|c| c.trim().parse::<usize>().ok())
        .filter(|&n| n > 0)
    {
        // Fails only if the pool was already made: it then keeps its threads.
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global();
    }
}

/// `N threads` (or `1 thread`): the pool's, for a tool's first line.
pub fn threads() -> String {
    match rayon::current_num_threads() {
        1 => "1 thread".into(),
        n => format!("{n} threads"),
    }
}

/// Bad usage found after parsing (an option's value out of its range): exit code 2, as clap's
/// own errors.
#[derive(Debug)]
pub struct Usage(pub String);

impl std::fmt::Display for Usage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Usage {}

/// An [`anyhow::Error`] of bad usage (exit code 2).
pub fn usage(msg: impl Into<String>) -> anyhow::Error {
    Usage(msg.into()).into()
}

/// Whether an error is, or wraps, a write into a closed pipe: as an I/O error, or inside the
/// CSV and JSON writers' errors (which do not expose it as their source).
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    let broken = io::ErrorKind::BrokenPipe;
    e.chain().any(|c| {
        c.downcast_ref::<io::Error>()
            .is_some_and(|io| io.kind() == broken)
            || c.downcast_ref::<csv::Error>()
                .is_some_and(|e| matches!(e.kind(), csv::ErrorKind::Io(io) if io.kind() == broken))
            || c.downcast_ref::<serde_json::Error>()
                .is_some_and(|e| e.io_error_kind() == Some(broken))
    })
}

/// Buffered standard output (flush it with `flush()?` so errors are seen).
pub fn stdout() -> BufWriter<io::StdoutLock<'static>> {
    BufWriter::with_capacity(1 << 16, io::stdout().lock())
}

/// Writes a picture as PNG to standard output.
pub fn write_png_stdout(img: &crate::draw::render::Image) -> anyhow::Result<()> {
    use anyhow::Context;
    use std::io::Write;
    let mut png = Vec::new();
    img.write_png(&mut png).context("encoding the PNG")?;
    let mut out = stdout();
    out.write_all(&png)?;
    out.flush()?;
    Ok(())
}

/// The error for an input stream without objects.
pub fn require_objects(n: u64) -> anyhow::Result<()> {
    if n == 0 {
        anyhow::bail!("the input holds no objects (expected an OBJ stream on standard input)");
    }
    Ok(())
}

/// The mass properties of `obj` once it is known to be a solid: closed, consistently oriented,
/// faces outwards. Errors name the object and its line.
pub fn solid(obj: &ObjObject) -> anyhow::Result<crate::geometry::mass::MassProps> {
    use anyhow::Context;
    let what = || format!("object '{}' (line {})", obj.mesh.name, obj.line);
    obj.mesh
        .topology(Some(&obj.face_lines))
        .with_context(what)?;
    let props = crate::geometry::mass::MassProps::of(&obj.mesh);
    // Flat: no volume against the cube of its extent, to round-off.
    let extent = crate::math::extent(&obj.mesh.vertices);
    if props.volume.abs() <= 1e-12 * crate::math::cube(extent) {
        anyhow::bail!(
            "{}: encloses no volume ({:e}); a particle must be a solid",
            what(),
            props.volume
        );
    }
    if props.volume.is_nan() || props.volume <= 0.0 {
        anyhow::bail!(
            "{}: the faces point inwards (volume {:e}); faces must be counter-clockwise seen from outside",
            what(),
            props.volume
        );
    }
    Ok(props)
}

/// An output file's folder must exist: checked before the work, so that a long run does not
/// fail at its end for a typing error.
pub fn check_output(path: Option<&std::path::Path>, flag: &str) -> anyhow::Result<()> {
    if let Some(p) = path {
        if let Some(d) = p.parent().filter(|d| !d.as_os_str().is_empty()) {
            if !d.is_dir() {
                anyhow::bail!(
                    "{flag} {}: the folder {} does not exist",
                    p.display(),
                    d.display()
                );
            }
        }
    }
    Ok(())
}

/// Buffered standard input (movable to another thread, so reading can overlap work).
pub fn stdin() -> io::BufReader<io::Stdin> {
    io::BufReader::with_capacity(1 << 16, io::stdin())
}

/// The provenance comment a tool adds to a stream: ` tool version args...` (no leading `#`).
pub fn provenance(tool: &str) -> String {
    let args: Vec<String> = std::env::args().skip(1).collect();
    format!(" {tool} {} {}", env!("CARGO_PKG_VERSION"), args.join(" "))
        .trim_end()
        .to_string()
}

/// The name that prefixes every line a tool writes on standard error, `[NAME] tool: ...`:
/// the environment's `GRANULAR_TAG` (the Makefile sets it to each target, so that the lines of
/// parallel jobs can be told apart), or none.
pub fn tag() -> Option<&'static str> {
    static TAG: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    TAG.get_or_init(|| {
        std::env::var("GRANULAR_TAG")
            .ok()
            .filter(|t| !t.trim().is_empty())
    })
    .as_deref()
}

/// What starts a tool's line on standard error: `[tag] tool: `, or `tool: `.
pub fn prefix(tool: &str) -> String {
    match tag() {
        Some(t) => format!("[{t}] {tool}: "),
        None => format!("{tool}: "),
    }
}

/// Seconds between progress lines in a log (standard error not a terminal, or a parallel
/// make): `GRANULAR_PROGRESS_SECONDS`, default 5.
fn log_interval() -> Duration {
    let secs = std::env::var("GRANULAR_PROGRESS_SECONDS")
        .ok()
        .and_then(|s| s.trim().parse::<f64>().ok())
        .filter(|s| s.is_finite() && *s >= 0.0)
        .unwrap_or(5.0);
    Duration::from_secs_f64(secs.min(86_400.0))
}

/// Whether this process runs under a make that runs jobs in parallel (`make -j`): their
/// lines redrawn in place on one terminal would overwrite each other.
fn under_parallel_make() -> bool {
    std::env::var("MAKEFLAGS").is_ok_and(|f| {
        f.split_whitespace()
            .any(|w| w.starts_with("-j") || w.starts_with("--jobserver"))
    })
}

/// How progress is shown.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Show {
    /// One line redrawn in place (standard error is a terminal).
    Live,
    /// A line of its own every [`log_interval`] (a log, or parallel jobs on a terminal).
    Lines,
    /// Nothing (`--quiet`).
    Off,
}

/// Progress and messages on standard error, each line prefixed as [`prefix`] says. A status
/// ([`Progress::status`]) is shown at most every half second, redrawn in place on a terminal,
/// or as a line of its own every few seconds in a log ([`log_interval`]); a message
/// ([`Progress::say`]) always stays. Shared between threads.
pub struct Progress {
    prefix: String,
    show: Show,
    every: Duration,
    start: Instant,
    /// When the last status was shown, and whether it is a live line still on screen.
    shown: std::sync::Mutex<(Option<Instant>, bool)>,
}

impl Progress {
    pub fn new(tool: &'static str) -> Self {
        let live = io::stderr().is_terminal() && !under_parallel_make();
        let (show, every) = if live {
            (Show::Live, Duration::from_millis(500))
        } else {
            (Show::Lines, log_interval())
        };
        Progress {
            prefix: prefix(tool),
            show,
            every,
            start: Instant::now(),
            shown: std::sync::Mutex::new((None, false)),
        }
    }

    /// Progress that shows nothing, messages included (a tool's `--quiet`).
    pub fn quiet(tool: &'static str) -> Self {
        Progress {
            show: Show::Off,
            ..Progress::new(tool)
        }
    }

    /// Seconds since the progress was made.
    pub fn elapsed(&self) -> f64 {
        self.start.elapsed().as_secs_f64()
    }

    /// Shows the status `line()` makes, if the last was shown long enough ago (in a log, the
    /// first comes one interval after the start); `line` is not called otherwise.
    pub fn status(&self, line: impl FnOnce() -> String) {
        if self.show == Show::Off {
            return;
        }
        let mut shown = self.shown.lock().unwrap_or_else(|p| p.into_inner());
        if shown.0.unwrap_or(self.start).elapsed() < self.every {
            return;
        }
        let text = line();
        let mut err = io::stderr().lock();
        let _ = match self.show {
            Show::Live => write!(err, "\r\x1b[K{}{text}", self.prefix),
            _ => writeln!(err, "{}{text}", self.prefix),
        };
        let _ = err.flush();
        *shown = (Some(Instant::now()), self.show == Show::Live);
    }

    /// Writes a message that stays, on a line of its own (after a live status, if one is on
    /// screen).
    pub fn say(&self, msg: &str) {
        if self.show == Show::Off {
            return;
        }
        let mut shown = self.shown.lock().unwrap_or_else(|p| p.into_inner());
        let mut err = io::stderr().lock();
        let clear = if shown.1 { "\r\x1b[K" } else { "" };
        let _ = writeln!(err, "{clear}{}{msg}", self.prefix);
        shown.1 = false;
    }

    /// Reports `done` units of `what` (of `total`, when known: with the share done and the
    /// time left at the rate so far).
    pub fn tick(&self, done: u64, total: Option<u64>, what: &str) {
        self.status(|| {
            let secs = self.elapsed();
            match total.filter(|&t| t > 0 && done > 0) {
                Some(t) => format!(
                    "{done} of {t} {what} ({:.0} %), {secs:.0} s, about {} left",
                    100.0 * done as f64 / t as f64,
                    duration(secs * (t.saturating_sub(done)) as f64 / done as f64)
                ),
                None => format!("{done} {what} ({secs:.1} s)"),
            }
        })
    }

    /// Ends a live status line, if one is on screen.
    pub fn finish(&self) {
        let mut shown = self.shown.lock().unwrap_or_else(|p| p.into_inner());
        if shown.1 {
            eprintln!();
            shown.1 = false;
        }
    }
}

/// A duration for people: `42 s`, `7 min`, `2.5 h`.
pub fn duration(secs: f64) -> String {
    if !secs.is_finite() {
        "an unknown time".into()
    } else if secs < 90.0 {
        format!("{secs:.0} s")
    } else if secs < 5400.0 {
        format!("{:.0} min", secs / 60.0)
    } else {
        format!("{:.1} h", secs / 3600.0)
    }
}

/// What a batched stream pass hands back, in input order.
pub enum Emit<T> {
    Comment(String),
    Done(T),
}

/// The OBJ output of a tool that turns each object of a stream into meshes: comments between
/// objects pass through, and the tool's provenance comment goes before its first object.
pub struct ObjOut<W: io::Write> {
    out: crate::geometry::obj::ObjWriter<W>,
    provenance: Option<String>,
}

impl<W: io::Write> ObjOut<W> {
    pub fn new(tool: &str, out: W) -> Self {
        ObjOut {
            out: crate::geometry::obj::ObjWriter::new(out),
            provenance: Some(provenance(tool)),
        }
    }

    /// Writes one item handed over by [`for_each_object`]: meshes made of one input object,
    /// with that object's comments.
    pub fn emit(
        &mut self,
        item: Emit<(Vec<crate::geometry::mesh::PolyMesh>, Vec<String>)>,
    ) -> io::Result<()> {
        match item {
            Emit::Comment(c) => self.out.comment(&c),
            Emit::Done((meshes, comments)) => {
                if let Some(p) = self.provenance.take() {
                    self.out.comment(&p)?;
                }
                meshes
                    .iter()
                    .try_for_each(|m| self.out.object(m, &comments))
            }
        }
    }

    /// Flushes the output.
    pub fn finish(self) -> io::Result<()> {
        self.out.into_inner()?.flush()
    }
}

/// Reads an OBJ stream and runs `work` on each object, `batch` objects at a time in parallel,
/// handing comments and results to `emit` in input order. Stops at the first error in input
/// order, after emitting everything before it (so no object is half-written). Returns the number
/// of objects; memory holds one batch.
pub fn for_each_object<R: BufRead + Send, T: Send>(
    tool: &'static str,
    input: R,
    batch: usize,
    work: impl Fn(ObjObject) -> anyhow::Result<T> + Sync,
    mut emit: impl FnMut(Emit<T>) -> anyhow::Result<()>,
) -> anyhow::Result<u64> {
    let mut reader = ObjReader::new(input);
    let progress = Progress::new(tool);
    let mut count = 0u64;
    // Reading the next batch overlaps with the work on this one.
    let mut current = read_batch(&mut reader, batch);
    loop {
        let (items, read_error) = current;
        if items.is_empty() && read_error.is_none() {
            progress.finish();
            return Ok(count);
        }
        let more = read_error.is_none();
        let (results, next) = rayon::join(
            || {
                items
                    .into_par_iter()
                    .map(|item| match item {
                        Item::Comment(c) => Ok(Emit::Comment(c)),
                        Item::Object(o) => work(o).map(Emit::Done),
                    })
                    .collect::<Vec<anyhow::Result<Emit<T>>>>()
            },
            || {
                if more {
                    read_batch(&mut reader, batch)
                } else {
                    (Vec::new(), None)
                }
            },
        );
        for r in results {
            let e = r?;
            count += matches!(e, Emit::Done(_)) as u64;
            emit(e)?;
        }
        progress.tick(count, None, "objects");
        if let Some(e) = read_error {
            return Err(e.into());
        }
        current = next;
    }
}

/// Up to `batch` objects (with the comments among them), and the read error that ended the
/// batch early, if any.
fn read_batch<R: BufRead>(
    reader: &mut ObjReader<R>,
    batch: usize,
) -> (Vec<Item>, Option<crate::geometry::obj::ObjError>) {
    let mut items = Vec::new();
    let mut objects = 0;
    while objects < batch {
        match reader.next() {
            None => break,
            Some(Err(e)) => return (items, Some(e)),
            Some(Ok(item)) => {
                objects += matches!(item, Item::Object(_)) as usize;
                items.push(item);
            }
        }
    }
    (items, None)
}

/// Parses `N` or `A..B` (inclusive) into a range of integers.
pub fn parse_range<T: std::str::FromStr + PartialOrd + Copy>(s: &str) -> Result<(T, T), String> {
    let parse = |x: &str| {
        x.trim()
            .parse::<T>()
            .map_err(|_| format!("'{x}' is not a whole number"))
    };
    match s.split_once("..") {
        Some((a, b)) => {
            let (a, b) = (parse(a)?, parse(b.trim_start_matches('='))?);
            if a > b {
                return Err(format!("empty range '{s}': the start is after the end"));
            }
            Ok((a, b))
        }
        None => parse(s).map(|a| (a, a)),
    }
}

/// `eprintln!` for a tool's message: `note!("pack", "{n} particles")` writes the line after
/// the tool's [`prefix`] (`[tag] pack: ` or `pack: `).
#[macro_export]
macro_rules! note {
    ($tool:expr, $($arg:tt)*) => {
        eprintln!("{}{}", $crate::cli::prefix($tool), format_args!($($arg)*))
    };
}
