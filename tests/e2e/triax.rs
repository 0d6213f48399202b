//! The `triax` tool: the quick pipe polygen | pack | triax, a resumed run equal to the whole
//! one, 1 and 2 threads, and broken input and options.

use super::{fails, fixture, ok, repo_file, run_env};

/// A small pack specimen (36 particles of 12-18 mm in a 70 x 140 mm cylinder), made once.
pub fn specimen() -> &'static [u8] {
    static SPEC: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    SPEC.get_or_init(|| {
        let nine = fixture("templates_seed7.obj");
        ok(
            "pack",
            &[
                "--count",
                "36",
                "--diameter",
                "0.07",
                "--height",
                "0.14",
                "--size-min",
                "0.012",
                "--size-max",
                "0.018",
                "--seed",
                "3",
                "--every",
                "100000",
            ],
            &nine,
        )
    })
}

/// The options of the tests' short test: 2 % of axial strain, fast, with checkpoints in
/// consolidation.
const SHORT: [&str; 10] = [
    "--final-strain",
    "0.02",
    "--rate",
    "2",
    "--every",
    "0.002",
    "--frame-every",
    "0.01",
    "--checkpoint-every",
    "2000",
];

/// The short test's stream, run once.
pub fn short_stream() -> &'static [u8] {
    static STREAM: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    STREAM.get_or_init(|| ok("triax", &SHORT, specimen()))
}

fn records(stream: &[u8]) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(stream)
        .lines()
        .map(|l| serde_json::from_str(l).expect("a JSON line"))
        .collect()
}

/// The pipe of the README: polygen | pack | triax, with its stream, summary and table: the
/// settings first, a measurement every 0.2 % from 0 to 2 %, frames (complete dem states) at
/// 0, 1 and 2 %, the last line the end of a state; q rises from about zero, and any frame
/// runs on in dem.
#[test]
fn the_pipe_runs_a_short_test_and_its_frames_are_dem_states() {
    let dir = std::env::temp_dir().join(format!("triax-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (summary, csv) = (dir.join("s.json"), dir.join("m.csv"));
    let mut args = SHORT.to_vec();
    args.extend([
        "--summary",
        summary.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
    ]);
    let out = ok("triax", &args, specimen());
    let recs = records(&out);
    assert_eq!(recs[0]["type"], "triax");
    assert_eq!(recs[0]["format"], "granular-triax");
    let measures: Vec<&serde_json::Value> =
        recs.iter().filter(|r| r["type"] == "measure").collect();
    assert_eq!(
        measures.len(),
        16,
        "measurements at 0.2 % / 32, / 16, / 8, / 4, / 2, then every 0.2 % from 0 to 2 %"
    );
    let q: Vec<f64> = measures
        .iter()
        .map(|m| m["q_boundary"].as_f64().unwrap())
        .collect();
    // At the start the platens hold the specimen's own vertical stress at the pressure (their
    // q over the end rings' area, Eq. 20, is below it: the sleeve's sags, docs/models/triax.md).
    let vertical = measures[0]["stress"][2].as_f64().unwrap();
    assert!(
        (vertical - 1e5).abs() < 0.02 * 1e5,
        "vertical contact stress at the start {vertical}"
    );
    assert!(
        q.iter().skip(1).all(|x| x - q[0] > 1e4),
        "q under load {q:?}"
    );
    for m in &measures {
        let p = m["p"].as_f64().unwrap();
        assert!(p > 5e4 && p < 3e5, "contact p {p}");
        assert!(m["coordination"].as_f64().unwrap() > 0.0);
    }
    let phase =
        |r: &serde_json::Value, p: &str| r["type"] == "frame" && r["progress"]["phase"] == p;
    let frames: Vec<&serde_json::Value> = recs.iter().filter(|r| phase(r, "loading")).collect();
    assert_eq!(frames.len(), 3, "frames at 0, 1 and 2 %");
    let checkpoints: Vec<&serde_json::Value> = (recs.iter())
        .filter(|r| phase(r, "consolidation"))
        .collect();
    assert_eq!(
        recs.last().unwrap()["type"],
        "energy",
        "the stream ends with a whole state"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    for key in [
        "peak_q",
        "e50",
        "e50_strain",
        "poisson_ratio",
        "friction_angle",
        "dilatancy_angle",
    ] {
        assert!(s[key].as_f64().is_some_and(f64::is_finite), "{key}: {s}");
    }
    // The test's own steps: consolidation's from the specimen to the first measurement,
    // loading's from there to the last frame (pack's steps are not counted).
    let step = |r: &serde_json::Value| r["step"].as_u64().unwrap();
    let clock = records(specimen())
        .into_iter()
        .find(|r| r["type"] == "clock");
    let (start, first) = (step(&clock.unwrap()), step(measures[0]));
    assert_eq!(
        s["consolidation_steps"].as_u64(),
        Some(first - start),
        "{s}"
    );
    assert_eq!(
        s["loading_steps"].as_u64(),
        Some(step(frames[2]) - first),
        "{s}"
    );
    assert_eq!(s["steps"].as_u64(), Some(step(frames[2]) - start), "{s}");
    // Checkpoints in consolidation every 2 000 of its steps (--checkpoint-every), before it
    // ended; it ends at the end of a block of 500 (--balance-window).
    let consolidation = first - start;
    assert!(
        consolidation > 2_000,
        "too short to checkpoint: {consolidation} steps"
    );
    assert_eq!(consolidation % 500, 0, "{consolidation} steps");
    let at: Vec<u64> = checkpoints.iter().map(|r| step(r) - start).collect();
    let due: Vec<u64> = (1..)
        .map(|k| k * 2_000)
        .take_while(|&k| k < consolidation)
        .collect();
    assert_eq!(
        at, due,
        "checkpoints in {consolidation} steps of consolidation"
    );
    let table = std::fs::read_to_string(&csv).unwrap();
    assert_eq!(table.lines().count(), 17);
    // The table's nominal strains are the ones each measurement was due at.
    let mut rows = csv::Reader::from_reader(table.as_bytes());
    let column = rows
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "nominal_strain");
    let nominal: Vec<f64> = rows
        .records()
        .map(|r| r.unwrap()[column.unwrap()].parse().unwrap())
        .collect();
    let due: Vec<f64> = [0.0, 1.0 / 32.0, 1.0 / 16.0, 0.125, 0.25, 0.5]
        .into_iter()
        .map(|f| f * 0.002)
        .chain((1..=10).map(|k| k as f64 * 0.002))
        .collect();
    for (n, d) in nominal.iter().zip(&due) {
        assert!((n - d).abs() < 1e-12, "nominal strains {nominal:?}");
    }
    // The last frame is a dem state with the membrane: dem runs on from it.
    let later = ok("dem", &["--frame", "last", "--steps", "20"], &out);
    assert!(String::from_utf8_lossy(&later).contains("\"membrane\""));
    std::fs::remove_dir_all(&dir).ok();
}

/// The platens' sudden start (`--ramp 0`) sends a stress wave through the specimen: q at
/// 0.006 % of strain is several times what it is when they come up to speed over 0.2 % (the
/// default), where q stays low until the specimen is loaded (149 against 20-28 kPa here).
#[test]
fn a_smooth_start_sends_no_stress_wave_through_the_specimen() {
    let early_q = |ramp: &str| -> Vec<f64> {
        let args = [
            "--final-strain",
            "0.002",
            "--rate",
            "2",
            "--every",
            "0.002",
            "--ramp",
            ramp,
        ];
        records(&ok("triax", &args, specimen()))
            .iter()
            .filter(|r| r["type"] == "measure")
            .map(|m| m["q_boundary"].as_f64().unwrap())
            .collect()
    };
    let (sudden, smooth) = (early_q("0"), early_q("0.002"));
    let largest = |q: &[f64]| q.iter().copied().fold(f64::MIN, f64::max);
    assert_eq!((sudden.len(), smooth.len()), (7, 7), "0, 5 halvings, 0.2 %");
    assert!(
        largest(&smooth) < 0.5 * largest(&sudden),
        "largest q in the first 0.2 %: smooth start {smooth:?}, sudden {sudden:?}"
    );
    assert!(
        smooth[1] < 0.3 * sudden[1],
        "q at 0.006 %: smooth {}, sudden {}",
        smooth[1],
        sudden[1]
    );
}

/// A run stopped at a frame, in loading or at a checkpoint in consolidation, and resumed from
/// its stream writes, together, the bytes of the run in one go; 1 and 2 threads write the
/// same bytes.
#[test]
fn a_resumed_test_and_any_thread_count_give_the_same_bytes() {
    let whole = short_stream().to_vec();
    let mut stop = SHORT.to_vec();
    stop.extend(["--stop-at", "0.01"]);
    let part = ok("triax", &stop, specimen());
    assert!(part.len() < whole.len());
    let rest = ok("triax", &[], &part);
    let mut joined = part.clone();
    joined.extend(&rest);
    assert!(
        joined == whole,
        "stopped and resumed differs from the run in one go"
    );
    // Stopped in consolidation: the stream cut after its first checkpoint's state resumes
    // from there, to the same bytes.
    let text = String::from_utf8_lossy(&whole).to_string();
    let lines: Vec<&str> = text.lines().collect();
    let (at, count) = (lines.iter().enumerate())
        .find_map(|(i, l)| {
            let r: serde_json::Value = serde_json::from_str(l).ok()?;
            let checkpoint = r["type"] == "frame" && r["progress"]["phase"] == "consolidation";
            checkpoint.then(|| (i, r["records"].as_u64().unwrap() as usize))
        })
        .expect("a checkpoint in consolidation");
    let mut cut = (lines[..=at + count].join("\n") + "\n").into_bytes();
    // The checkpoints' spacing is an option, not a setting of the stream: given again.
    let rest = ok("triax", &["--checkpoint-every", "2000"], &cut);
    cut.extend(&rest);
    assert!(
        cut == whole,
        "resumed in consolidation differs from the run in one go"
    );
    // Resuming a finished stream does nothing.
    assert!(ok("triax", &[], &whole).is_empty());
    let one = run_env("triax", &SHORT, specimen(), &[("RAYON_NUM_THREADS", "1")]);
    assert!(one.status.success());
    assert!(one.stdout == whole, "1 thread differs from 2");
}

/// A test resumed from its first checkpoint in consolidation writes, with the part before it,
/// every record of the run in one go, field by field: on 72 particles of 30-40 mm, whose body
/// pairs come in more than one chunk of the narrow phase. The chunks follow the broad phase's
/// kept list, which a restart makes anew: the unbalanced-force ratio's sum, taken chunk by
/// chunk, once differed in its last digits after a resume, and so the step at which
/// consolidation ended.
#[test]
fn a_test_resumed_in_consolidation_equals_the_run_in_one_go_field_by_field() {
    let spec = ok(
        "pack",
        &[
            "--diameter",
            "0.12",
            "--height",
            "0.24",
            "--size-min",
            "0.03",
            "--size-max",
            "0.04",
        ],
        &fixture("templates_seed7.obj"),
    );
    let opts = [
        "--final-strain",
        "0.01",
        "--rate",
        "2",
        "--checkpoint-every",
        "2000",
    ];
    let whole = ok("triax", &opts, &spec);
    let recs = records(&whole);
    let (at, count) = (recs.iter().enumerate())
        .find_map(|(i, r)| {
            let checkpoint = r["type"] == "frame" && r["progress"]["phase"] == "consolidation";
            checkpoint.then(|| (i, r["records"].as_u64().unwrap() as usize))
        })
        .expect("a checkpoint in consolidation");
    let lines: Vec<&[u8]> = whole.split_inclusive(|&b| b == b'\n').collect();
    let mut joined = lines[..=at + count].concat();
    let rest = ok("triax", &opts, &joined);
    joined.extend(&rest);
    let again = records(&joined);
    for (k, (a, b)) in again.iter().zip(&recs).enumerate() {
        let (a, b) = (a.as_object().unwrap(), b.as_object().unwrap());
        let differ: Vec<String> = (a.iter())
            .filter(|(f, v)| b.get(*f) != Some(*v))
            .map(|(f, v)| format!("{f}: {v} resumed, {:?} in one go", b.get(f)))
            .collect();
        assert!(
            differ.is_empty() && a.len() == b.len(),
            "record {} (line {}) differs after the resume at line {}: {}",
            k + 1,
            k + 1,
            at + count + 1,
            differ.join("; ")
        );
    }
    assert_eq!(again.len(), recs.len(), "the resumed stream's length");
    assert!(joined == whole, "the bytes differ");
}

/// Progress as a log shows it (standard error not a terminal): every line starts with the
/// tag the Makefile sets (GRANULAR_TAG), consolidation says its step, the unbalanced ratio and
/// what it must fall below, loading its strain of the final one, q, steps a second and the time
/// left; the first line says the threads, taken in a Slurm job from its CPUs. The stream is the
/// same bytes as without progress.
#[test]
fn triax_shows_its_progress_tagged_and_takes_its_threads_from_slurm() {
    let out = super::run_env_without(
        "triax",
        &SHORT,
        specimen(),
        &[
            ("GRANULAR_TAG", "out/x.jsonl"),
            ("GRANULAR_PROGRESS_SECONDS", "0"),
            ("SLURM_CPUS_PER_TASK", "1"),
        ],
        &["RAYON_NUM_THREADS"],
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(out.stdout == short_stream(), "progress changed the stream");
    let lines: Vec<&str> = err.lines().collect();
    assert!(
        lines.iter().all(|l| l.starts_with("[out/x.jsonl] triax: ")),
        "{err}"
    );
    assert!(lines[0].ends_with("on 1 thread"), "{}", lines[0]);
    let consolidating = (lines.iter())
        .find(|l| l.contains("consolidation step"))
        .expect("a consolidation status");
    assert!(
        consolidating.contains("(ends below 5e-3)") && consolidating.contains("steps/s"),
        "{consolidating}"
    );
    let loading = (lines.iter())
        .find(|l| l.contains("axial strain") && l.contains("left"))
        .expect("a loading status");
    assert!(
        loading.contains(" of 0.02 (")
            && loading.contains(": q ")
            && loading.contains("steps/s, about"),
        "{loading}"
    );
}

/// Bad input and options: a clear message, exit 1 (2 for bad usage), nothing written.
#[test]
fn triax_rejects_what_is_not_a_cylindrical_specimen_and_nonsense_options() {
    let rejects = |args: &[&str], stdin: &[u8], code: i32, needles: &[&str]| {
        let out = fails("triax", args, stdin, code, needles);
        assert!(out.is_empty(), "triax {args:?} wrote output on failure");
    };
    rejects(&[], b"", 1, &["empty"]);
    rejects(&[], b"o cube\nv 0 0 0\n", 1, &["line 1"]);
    // A dem scene that is no pack specimen: six bodies over a floor.
    rejects(
        &[],
        &repo_file("examples/drop.jsonl"),
        1,
        &["not a pack specimen"],
    );
    // A specimen in a box.
    let nine = fixture("templates_seed7.obj");
    let boxed = ok(
        "pack",
        &[
            "--container",
            "box",
            "--count",
            "18",
            "--width",
            "0.07",
            "--depth",
            "0.07",
            "--height",
            "0.1",
            "--size-min",
            "0.012",
            "--size-max",
            "0.016",
        ],
        &nine,
    );
    rejects(&[], &boxed, 1, &["not a pack specimen", "a box"]);
    for (flag, value) in [
        ("--pressure", "-1e5"),
        ("--final-strain", "1"),
        ("--final-strain", "0"),
        ("--rate", "0"),
        ("--every", "nan"),
        ("--membrane-young", "0"),
        ("--membrane-poisson", "0.6"),
        ("--safety", "2"),
        ("--stop-at", "-1"),
        ("--ramp", "-0.001"),
        ("--ramp", "inf"),
        ("--opening", "31"),
    ] {
        rejects(&[flag, value], specimen(), 2, &[flag]);
    }
    rejects(&["--rate", "fast"], specimen(), 2, &["invalid value"]);
    rejects(
        &["--boundary", "sleeve"],
        specimen(),
        2,
        &["--boundary", "membrane or rigid"],
    );
    rejects(&["--boundary", "rigid"], &boxed, 1, &["a box"]);
    // Wall friction: the membrane's contacts have no shear law.
    let rough = String::from_utf8_lossy(specimen())
        .replace("\"wall_friction\":0.0", "\"wall_friction\":0.2");
    assert_ne!(
        rough.as_bytes(),
        specimen(),
        "the specimen names its wall friction"
    );
    rejects(
        &[],
        rough.as_bytes(),
        1,
        &["frictionless", "wall_friction must be 0, got 0.2"],
    );
    rejects(
        &["--summary", "/nonexistent/dir/s.json"],
        specimen(),
        1,
        &["--summary", "does not exist"],
    );
    // A truncated stream: its last frame cut short.
    let whole = short_stream().to_vec();
    let text = String::from_utf8_lossy(&whole);
    let cut = text.rfind("{\"type\":\"energy\"").unwrap();
    let (head, _) = text.split_at(cut);
    let head = &head[..head.trim_end().rfind('\n').unwrap()];
    rejects(&[], head.as_bytes(), 1, &["truncated"]);
    // Cut in the middle of a line.
    rejects(&[], &whole[..whole.len() - 40], 1, &["line"]);
}

/// An isotropic start at the quick scale: the nine I_P templates packed as `make figures`
/// packs its quick specimens (150 x 300 mm, 10-40 mm), consolidated with the defaults. At the
/// first measurement the contacts' stress with their wall halves (`stress`) is the pressure
/// along the axis within 2 %, and the deviator of its diagonal over p is below 0.03 (the
/// platens over the end rings' area left 0.15 there: the sleeve's sags made the rings' area
/// too large). The whole tensor's q/p adds the shear terms, the sampling floor of a few
/// hundred particles (0.06 on the quick I_P specimen, 0.007 on the paper's): below 0.1.
#[test]
fn consolidation_leaves_an_isotropic_start_at_quick_scale() {
    let nine = fixture("templates_seed7.obj");
    let spec = ok(
        "pack",
        &[
            "--diameter",
            "0.15",
            "--height",
            "0.3",
            "--every",
            "1000000",
        ],
        &nine,
    );
    let start = ok("triax", &["--stop-at", "0"], &spec);
    let first = records(&start)
        .into_iter()
        .find(|r| r["type"] == "measure")
        .expect("a measurement at the start of loading");
    let s: Vec<f64> = (first["stress"].as_array().expect("stress"))
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect();
    let p = (s[0] + s[1] + s[2]) / 3.0;
    let diagonal =
        (0.5 * ((s[0] - s[1]).powi(2) + (s[1] - s[2]).powi(2) + (s[2] - s[0]).powi(2))).sqrt();
    let ratio = first["ratio"].as_f64().expect("ratio");
    eprintln!(
        "start: stress {s:?} Pa, diagonal q/p {:.4}, q/p {ratio:.4}",
        diagonal / p
    );
    assert!((s[2] - 1e5).abs() < 0.02e5, "sigma_zz {} Pa", s[2]);
    assert!(diagonal / p < 0.03, "the diagonal's q/p {}", diagonal / p);
    assert!(ratio < 0.1, "q/p {ratio}");
}

/// The rigid boundary through the tool: the pack's cylinder stays (no membrane in the settings
/// or the frames), its servo holds its contacts' stress at the pressure (every measurement of
/// the short test within 3 %), the frames run on in dem, a run stopped at a frame and resumed
/// writes the bytes of the run in one go, 1 and 2 threads the same; a stream whose settings
/// name the other boundary than its walls is refused.
#[test]
fn the_rigid_boundary_holds_the_pressure_resumes_to_the_same_bytes_and_refuses_a_mismatch() {
    let mut args = SHORT.to_vec();
    args.extend(["--boundary", "rigid"]);
    let whole = ok("triax", &args, specimen());
    let recs = records(&whole);
    assert_eq!(recs[0]["params"]["boundary"], "rigid");
    assert_eq!(recs[0]["nodes"], 0);
    let measures: Vec<&serde_json::Value> =
        recs.iter().filter(|r| r["type"] == "measure").collect();
    assert_eq!(measures.len(), 16);
    for m in &measures {
        let lateral = m["membrane_stress"].as_f64().unwrap();
        assert!(
            (lateral - 1e5).abs() < 0.03e5,
            "cylinder's stress {lateral}"
        );
        assert_eq!(m["radius_mean"], m["radius_max"]);
    }
    let q_end = measures.last().unwrap()["q_boundary"].as_f64().unwrap();
    assert!(q_end > 1e4, "q at 2 %: {q_end}");
    assert!(!String::from_utf8_lossy(&whole).contains("\"membrane\":{"));
    ok("dem", &["--frame", "last", "--steps", "20"], &whole);
    let mut stop = args.clone();
    stop.extend(["--stop-at", "0.01"]);
    let part = ok("triax", &stop, specimen());
    assert!(part.len() < whole.len());
    let mut joined = part.clone();
    joined.extend(ok("triax", &[], &part));
    assert!(
        joined == whole,
        "stopped and resumed differs from the run in one go"
    );
    let one = run_env("triax", &args, specimen(), &[("RAYON_NUM_THREADS", "1")]);
    assert!(one.status.success());
    assert!(one.stdout == whole, "1 thread differs from 2");
    // Settings that name the other boundary than the frames' walls.
    let text = String::from_utf8_lossy(&part);
    let swapped = text.replacen("\"boundary\":\"rigid\"", "\"boundary\":\"membrane\"", 1);
    fails("triax", &[], swapped.as_bytes(), 1, &["not a membrane"]);
    let mut stop = SHORT.to_vec();
    stop.extend(["--stop-at", "0.01"]);
    let membrane = ok("triax", &stop, specimen());
    let membrane = String::from_utf8_lossy(&membrane);
    let swapped = membrane.replacen("\"boundary\":\"membrane\"", "\"boundary\":\"rigid\"", 1);
    fails(
        "triax",
        &[],
        swapped.as_bytes(),
        1,
        &["rigid boundary", "not a cylinder"],
    );
}

/// A hold through the tool (`--hold`): from the frame at 1 % of strain, the platens slow down
/// and stay where they are while the rigid boundary keeps the pressure; q and the unbalanced
/// ratio fall and fewer contacts slide than in loading; resumed, the held stream loads on to the
/// final strain, and the summary leaves the hold's measurements out. The membrane's hold, the
/// same. Bad --hold values are refused.
#[test]
fn a_hold_keeps_the_platens_still_relaxes_the_specimen_and_loads_on_when_resumed() {
    let mut args = SHORT.to_vec();
    args.extend(["--boundary", "rigid", "--stop-at", "0.01"]);
    let part = ok("triax", &args, specimen());
    let held = ok("triax", &["--hold", "6000", "--hold-every", "2000"], &part);
    let before = records(&part);
    let last = before
        .iter()
        .rev()
        .find(|r| r["type"] == "measure")
        .unwrap();
    let recs = records(&held);
    let measures: Vec<&serde_json::Value> =
        recs.iter().filter(|r| r["type"] == "measure").collect();
    let frames = recs.iter().filter(|r| r["type"] == "frame").count();
    assert_eq!((measures.len(), frames), (3, 3));
    let num = |r: &serde_json::Value, k: &str| r[k].as_f64().unwrap();
    // Slowed down over the ramp's 0.2 % of strain (to 1 % in steps; 0.002 s at 2 /s, under 2 000 steps),
    // then still.
    let (from, held_at) = (num(last, "axial_strain"), num(measures[0], "axial_strain"));
    assert!(
        held_at > from && held_at < from + 0.00202,
        "{from} then {held_at}"
    );
    for (k, m) in measures.iter().enumerate() {
        assert_eq!(
            m["axial_strain"], measures[0]["axial_strain"],
            "the platens moved"
        );
        assert_eq!(num(m, "step"), num(last, "step") + 2000.0 * (k + 1) as f64);
        let lateral = num(m, "membrane_stress");
        assert!(
            (lateral - 1e5).abs() < 0.03e5,
            "cylinder's stress {lateral}"
        );
    }
    let end = measures[2];
    eprintln!(
        "q {} -> {}, unbalanced {} -> {}",
        num(last, "q_boundary"),
        num(end, "q_boundary"),
        num(last, "unbalanced"),
        num(end, "unbalanced")
    );
    assert!(num(end, "q_boundary") < num(last, "q_boundary"));
    assert!(num(end, "unbalanced") < num(last, "unbalanced"));
    // The sliding ratio of the last loading frame against the held frames'.
    let mut joined = part.clone();
    joined.extend(&held);
    let rows: Vec<serde_json::Value> =
        String::from_utf8(ok("fabric", &["--json", "--quiet"], &joined))
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
    let sliding: Vec<f64> = rows.iter().map(|r| num(r, "sliding_ratio")).collect();
    eprintln!("sliding ratio by frame: {sliding:?}");
    let n = sliding.len();
    assert!(sliding[n - 1] < sliding[n - 4], "{sliding:?}");
    // Loading goes on from the held state to the final strain.
    let rest = ok("triax", &[], &joined);
    let out = records(&rest);
    let fin = out.iter().rev().find(|r| r["type"] == "measure").unwrap();
    assert!(num(fin, "axial_strain") >= 0.02, "{}", fin["axial_strain"]);
    joined.extend(&rest);
    let dir = std::env::temp_dir().join(format!("triax-hold-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("summary.json");
    ok("triax", &["--summary", path.to_str().unwrap()], &joined);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert!(num(&s, "dilatancy_angle").is_finite(), "{s}");
    assert!(num(&s, "poisson_ratio").is_finite(), "{s}");
    // The membrane's hold: the sleeve stays at the cell pressure, nothing escapes, q falls.
    let mut args = SHORT.to_vec();
    args.extend(["--stop-at", "0.01"]);
    let part_m = ok("triax", &args, specimen());
    let held_m = records(&ok(
        "triax",
        &["--hold", "4000", "--hold-every", "2000"],
        &part_m,
    ));
    let before = records(&part_m);
    let last_m = before
        .iter()
        .rev()
        .find(|r| r["type"] == "measure")
        .unwrap();
    let measures: Vec<&serde_json::Value> =
        held_m.iter().filter(|r| r["type"] == "measure").collect();
    assert_eq!(measures.len(), 2);
    assert_eq!(measures[0]["axial_strain"], measures[1]["axial_strain"]);
    assert!(num(measures[1], "q_boundary") < num(last_m, "q_boundary"));
    assert!(num(measures[1], "unbalanced") < num(last_m, "unbalanced"));
    // Bad input.
    fails("triax", &["--hold", "0"], &part, 2, &["--hold"]);
    fails(
        "triax",
        &["--hold", "10", "--hold-every", "0"],
        &part,
        2,
        &["--hold-every"],
    );
    fails(
        "triax",
        &["--hold", "10", "--stop-at", "0.01"],
        &part,
        2,
        &["--stop-at"],
    );
    fails("triax", &["--hold-every", "10"], &part, 2, &["--hold"]);
}
