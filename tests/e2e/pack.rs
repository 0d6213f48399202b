//! The `pack` tool: broken input and arguments, and a small specimen that must meet the
//! final-state conditions (with the same bytes on 1 and 2 threads), in a cylinder and a box.

use super::{fails, fixture, inside_out_cube, ok, run, run_env};

/// Runs pack on bad input: exit 1 (2 for usage: an option out of its range), the message holds every needle, no output.
fn rejects(args: &[&str], stdin: &[u8], code: i32, needles: &[&str]) {
    let out = fails("pack", args, stdin, code, needles);
    assert!(out.is_empty(), "pack {args:?} wrote output on failure");
}

#[test]
fn pack_rejects_broken_templates_and_arguments() {
    let nine = fixture("templates_seed7.obj");
    rejects(&[], b"", 1, &["no objects"]);
    rejects(&[], b"# nothing\n", 1, &["no objects"]);
    let open = "o open\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n";
    rejects(
        &[],
        open.as_bytes(),
        1,
        &["'open'", "line 1", "boundary edge"],
    );
    rejects(&[], &inside_out_cube(), 1, &["'cube'", "point inwards"]);
    rejects(
        &["--size-min", "0.03", "--size-max", "0.02"],
        &nine,
        2,
        &["--size-min 0.03 is above the largest size 0.02"],
    );
    rejects(
        &["--diameter", "0.05", "--height", "0.1"],
        &nine,
        1,
        &["more than the container's diameter"],
    );
    for (flag, value) in [
        ("--pressure", "-1"),
        ("--diameter", "0"),
        ("--porosity", "1.2"),
        ("--prep-friction", "-0.1"),
        ("--tolerance", "nan"),
        ("--count", "0"),
        ("--count", "2"),
        ("--damping", "1"),
        ("--kn", "0"),
    ] {
        rejects(&[flag, value], &nine, 2, &[flag]);
    }
    rejects(&["--size-min", "ten"], &nine, 2, &["invalid value"]);
    rejects(
        &["--size-min", "1e-5", "--size-max", "2e-5"],
        &nine,
        1,
        &["more than 1000000 particles"],
    );
    rejects(
        &["--relative-density", "1.5"],
        &nine,
        2,
        &["--relative-density must be in [0, 1]"],
    );
    rejects(
        &["--relative-density", "0.8", "--prep-friction", "0.2"],
        &nine,
        2,
        &["cannot be used with"],
    );
    rejects(
        &["--limits-only", "--relative-density", "0.8"],
        &nine,
        2,
        &["cannot be used with"],
    );
    rejects(
        &["--limits-only", "--calibration-scale", "1.5"],
        &nine,
        2,
        &["--calibration-scale must be in (0, 1]"],
    );
    rejects(
        &["--void-ratio-limits", "0.5"],
        &nine,
        2,
        &["expected E_MIN,E_MAX"],
    );
    rejects(
        &["--void-ratio-limits", "0.9,0.5"],
        &nine,
        2,
        &["0 < E_MIN < E_MAX"],
    );
    // The box's sides belong to the box, the diameter to the cylinder.
    rejects(&["--width", "0.2"], &nine, 2, &["--container box"]);
    rejects(
        &["--container", "box", "--diameter", "0.2"],
        &nine,
        2,
        &["--diameter is the cylinder's"],
    );
    rejects(
        &["--container", "box", "--depth", "0"],
        &nine,
        2,
        &["--depth must be a positive number"],
    );
    rejects(
        &["--container", "box", "--depth", "0.04"],
        &nine,
        1,
        &["more than the container's depth"],
    );
    rejects(
        &["--container", "sphere"],
        &nine,
        2,
        &["invalid value 'sphere'"],
    );
    // Refining the friction needs the target and the limits at full size.
    rejects(
        &["--refine-runs", "1", "--relative-density", "0.8"],
        &nine,
        2,
        &["--void-ratio-limits"],
    );
    // Too few steps to settle: a clear error, and no half-made specimen on standard output.
    rejects(
        &[
            "--count",
            "9",
            "--diameter",
            "0.1",
            "--height",
            "0.2",
            "--size-min",
            "0.012",
            "--size-max",
            "0.016",
            "--max-steps",
            "100",
        ],
        &nine,
        1,
        &["not in equilibrium after 100 steps", "--max-steps"],
    );
}

/// 36 particles of the nine templates, soft (kn = 1e6 N/m at 1 kPa: the paper's overlap per
/// size of 1e8 N/m at 100 kPa, at a 10 times longer time step).
const SOFT: [&str; 10] = [
    "--count",
    "36",
    "--diameter",
    "0.06",
    "--height",
    "0.12",
    "--size-min",
    "0.012",
    "--size-max",
    "0.02",
];

/// The soft specimens' contact law, pressure and loose strain rate.
const SOFT_LAW: [&str; 8] = [
    "--kn",
    "1e6",
    "--ks",
    "5e5",
    "--pressure",
    "1e3",
    "--loose-strain-rate",
    "4",
];

/// One summary field as a number.
fn field(summary: &serde_json::Value, key: &str) -> f64 {
    summary[key]
        .as_f64()
        .unwrap_or_else(|| panic!("no {key} in {summary}"))
}

#[test]
fn a_small_specimen_is_consolidated_isotropically_and_the_same_on_1_and_2_threads() {
    // The SOFT specimen. About a minute.
    let dir = std::env::temp_dir().join(format!("pack-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let nine = fixture("templates_seed7.obj");
    let runs: Vec<(Vec<u8>, serde_json::Value, String)> = std::thread::scope(|scope| {
        let handles: Vec<_> = ["1", "2"]
            .map(|threads| {
                let (dir, nine) = (&dir, &nine);
                scope.spawn(move || {
                    let path = dir.join(format!("summary{threads}.json"));
                    let args = [
                        "--void-ratio-limits",
                        "0.6,1.6",
                        "--summary",
                        path.to_str().unwrap(),
                        "--every",
                        "20000",
                    ];
                    // The run on one thread also writes VTK snapshots.
                    let vtk = dir.join("vtk");
                    let mut args: Vec<&str> =
                        SOFT.iter().chain(&SOFT_LAW).copied().chain(args).collect();
                    if threads == "1" {
                        args.extend(["--vtk", vtk.to_str().unwrap()]);
                    }
                    // Every progress status shown, each line tagged.
                    let env = [
                        ("RAYON_NUM_THREADS", threads),
                        ("GRANULAR_TAG", "spec"),
                        ("GRANULAR_PROGRESS_SECONDS", "0"),
                    ];
                    let out = run_env("pack", &args, nine, &env);
                    assert!(
                        out.status.success(),
                        "pack failed: {}",
                        String::from_utf8_lossy(&out.stderr)
                    );
                    let text = std::fs::read_to_string(&path).unwrap();
                    let err = String::from_utf8_lossy(&out.stderr).to_string();
                    (out.stdout, serde_json::from_str(&text).unwrap(), err)
                })
            })
            .into();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    // A snapshot every --every steps (20 000, from step 0) and one of the specimen.
    let pvd = std::fs::read_to_string(dir.join("vtk").join("particles.pvd")).unwrap();
    let snapshots = pvd.matches("<DataSet").count();
    std::fs::remove_dir_all(&dir).ok();
    assert!(
        runs[0].0 == runs[1].0,
        "1 and 2 threads gave different specimens"
    );
    let s = &runs[0].1;
    assert_eq!(field(s, "particles"), 36.0);
    // The progress: tagged lines, the run of how many, its phase and speed; the threads.
    let err = &runs[0].2;
    assert!(err.lines().all(|l| l.starts_with("[spec] pack: ")), "{err}");
    assert!(err.contains("on 1 thread\n"), "{err}");
    for needle in [
        "run 1 of 1 (specimen at friction 0.1000): compaction step 100: wall stresses",
        "(ends below 1e-2)",
        "equilibrium step",
        "(ends below 1e-3)",
        "steps/s",
    ] {
        assert!(err.contains(needle), "'{needle}' not in: {err}");
    }
    let expected = field(s, "steps") as usize / 20000 + 2;
    assert_eq!(
        snapshots,
        expected,
        "{snapshots} VTK snapshots in {} steps",
        field(s, "steps")
    );
    // The final state: every wall within 2 % of the target, equilibrium, nothing out
    // of the container, overlaps below 1 % of a size.
    let stresses = s["wall_stresses"].as_array().unwrap();
    for x in stresses {
        let x = x.as_f64().unwrap();
        assert!((x - 1e3).abs() <= 20.0, "wall stress {x} Pa");
    }
    assert!(field(s, "stress_error") <= 0.02);
    assert!(field(s, "unbalanced") <= 1e-3);
    assert_eq!(field(s, "outside"), 0.0);
    let overlap = field(s, "max_overlap");
    assert!(overlap > 0.0 && overlap < 0.01, "largest overlap {overlap}");
    // Compacted at one strain rate in every direction: the container keeps its 2:1 shape.
    let aspect = field(s, "height") / field(s, "diameter");
    assert!((aspect - 2.0).abs() < 0.02, "height / diameter {aspect}");
    let porosity = field(s, "porosity");
    assert!(porosity > 0.3 && porosity < 0.7, "porosity {porosity}");
    assert!(field(s, "coordination") > 3.0);
    // Dr against the limits given.
    let dr = (1.6 - field(s, "void_ratio")) / (1.6 - 0.6);
    assert!((field(s, "relative_density") - dr).abs() < 1e-12);
    // The specimen is a dem state: it reads back and runs on.
    let on = run_env("dem", &["--steps", "10"], &runs[0].0, &[]);
    assert!(
        on.status.success(),
        "{}",
        String::from_utf8_lossy(&on.stderr)
    );
    // Its bodies are numbered along space already: renumbering changes nothing.
    assert_eq!(
        ok("dem", &["--renumber", "--steps", "0"], &runs[0].0),
        ok("dem", &["--steps", "0"], &runs[0].0)
    );
}

#[test]
fn limits_measured_alone_are_the_calibrations_and_given_limits_set_the_reported_dr() {
    // The soft 36-particle specimen of the test above. `--limits-only` on the container itself,
    // and beside it a calibration on a sample of the same size (scale 1): the same two
    // compactions, so the same limits to the bit; given limits then make the specimen's Dr.
    // About a minute.
    let nine = fixture("templates_seed7.obj");
    let common: Vec<&str> = (SOFT.iter().chain(&SOFT_LAW).copied())
        .chain(["--calibration-scale", "1", "--every", "1000000"])
        .collect();
    let dir = std::env::temp_dir().join(format!("pack-limits-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("summary.json");
    let specimen_args: Vec<&str> = (common.iter().copied())
        .chain([
            "--relative-density",
            "0.5",
            "--calibration-runs",
            "0",
            "--void-ratio-limits",
            "0.9,1.8",
            "--refine-runs",
            "1",
            "--summary",
            path.to_str().unwrap(),
        ])
        .collect();
    let (limits, specimen) = std::thread::scope(|scope| {
        let limits = scope.spawn(|| {
            let args: Vec<&str> = common.iter().copied().chain(["--limits-only"]).collect();
            run("pack", &args, &nine)
        });
        let specimen = run("pack", &specimen_args, &nine);
        (limits.join().unwrap(), specimen)
    });
    for out in [&limits, &specimen] {
        assert!(
            out.status.success(),
            "pack failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let text = String::from_utf8(limits.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one JSON line: {text}");
    let l: serde_json::Value = serde_json::from_str(&text).unwrap();
    let (e_min, e_max) = (field(&l, "e_min"), field(&l, "e_max"));
    assert!(0.0 < e_min && e_min < e_max, "e_min {e_min}, e_max {e_max}");
    assert_eq!((field(&l, "particles"), field(&l, "scale")), (36.0, 1.0));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let c = &s["calibration"];
    assert_eq!((field(c, "e_min"), field(c, "e_max")), (e_min, e_max));
    // The sample's friction from its own limits, corrected by one compaction of the specimen
    // for the given ones; Dr against the given ones.
    let r = &s["refinement"];
    assert_eq!(field(r, "target"), 1.8 - 0.5 * (1.8 - 0.9));
    let runs = r["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 1);
    assert_eq!(runs[0][0].as_f64(), Some(field(c, "prep_friction")));
    let f = field(&s, "prep_friction");
    assert_eq!(f, field(r, "prep_friction"));
    assert!((0.0..=1.0).contains(&f), "preparation friction {f}");
    assert_eq!((field(&s, "e_min"), field(&s, "e_max")), (0.9, 1.8));
    let dr = (1.8 - field(&s, "void_ratio")) / (1.8 - 0.9);
    assert!((field(&s, "relative_density") - dr).abs() < 1e-12);
    assert!(!specimen.stdout.is_empty());
}

#[test]
fn a_small_specimen_in_a_box_holds_the_pressure_on_all_six_walls() {
    // 36 particles, soft as in the cylinder's test, in a box 60 x 50 x 120 mm: sides that differ
    // so that a wall mixed up with another shows. About 10 s.
    let dir = std::env::temp_dir().join(format!("pack-box-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("summary.json");
    let args = [
        "--container",
        "box",
        "--width",
        "0.06",
        "--depth",
        "0.05",
        "--height",
        "0.12",
        "--count",
        "36",
        "--size-min",
        "0.012",
        "--size-max",
        "0.02",
        "--size-measure",
        "circumscribed",
        "--summary",
        path.to_str().unwrap(),
        "--every",
        "20000",
    ];
    let args: Vec<&str> = args.iter().chain(&SOFT_LAW).copied().collect();
    let out = run("pack", &args, &fixture("templates_seed7.obj"));
    assert!(
        out.status.success(),
        "pack failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    assert_eq!(s["container"], "box");
    assert!(s.get("diameter").is_none(), "{s}");
    let stresses = s["wall_stresses"].as_array().unwrap();
    assert_eq!(stresses.len(), 6, "bottom, top and four sides: {s}");
    for x in stresses {
        let x = x.as_f64().unwrap();
        assert!((x - 1e3).abs() <= 20.0, "wall stress {x} Pa");
    }
    assert!(field(&s, "unbalanced") <= 1e-3);
    assert_eq!(field(&s, "outside"), 0.0);
    let overlap = field(&s, "max_overlap");
    assert!(overlap > 0.0 && overlap < 0.01, "largest overlap {overlap}");
    // One strain rate in every direction while compacting: the box keeps its proportions
    // (the equilibrium's per-wall servo moves the walls by a little).
    let (w, d, h) = (field(&s, "width"), field(&s, "depth"), field(&s, "height"));
    assert!((w / d - 1.2).abs() < 0.02, "width / depth {}", w / d);
    assert!((h / d - 2.4).abs() < 0.04, "height / depth {}", h / d);
    // The state's six plane walls are where the summary says: the x walls' offsets are
    // -x_min and x_max's distance apart by the width.
    let text = String::from_utf8(out.stdout.clone()).unwrap();
    let walls: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["type"] == "wall")
        .collect();
    assert_eq!(walls.len(), 6);
    assert!(walls.iter().all(|v| v["kind"] == "plane"));
    // Prepared at the preparation's damping, handed on with the material's (0.3 by default)
    // and its friction.
    let material: serde_json::Value = text
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .find(|v| v["type"] == "material")
        .unwrap();
    assert_eq!(material["damping"], 0.3);
    assert_eq!(material["friction"], 0.5);
    let offset = |k: usize| walls[k]["offset"].as_f64().unwrap();
    assert!(((-offset(3) - offset(2)) - w).abs() < 1e-12);
    assert!(((-offset(5) - offset(4)) - d).abs() < 1e-12);
    assert!(((-offset(1) - offset(0)) - h).abs() < 1e-12);
    // The specimen runs on in dem.
    let on = run("dem", &["--steps", "10"], &out.stdout);
    assert!(
        on.status.success(),
        "{}",
        String::from_utf8_lossy(&on.stderr)
    );
}

#[test]
fn a_stopped_pack_takes_its_finished_compactions_from_the_journal_and_writes_the_same_specimen() {
    // The soft 36-particle specimen at Dr 0.5: two limits' compactions and one refinement at
    // full scale (calibration scale 1), then the specimen. The uninterrupted run keeps its three
    // compactions in the journal; a run stopped while writing the third (its journal cut there)
    // takes the first two from it, runs the third again, and writes the same bytes. About 20 s.
    let nine = fixture("templates_seed7.obj");
    let dir = std::env::temp_dir().join(format!("pack-journal-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let journal = dir.join("spec.journal");
    let args: Vec<&str> = (SOFT.iter().chain(&SOFT_LAW).copied())
        .chain([
            "--calibration-scale",
            "1",
            "--every",
            "1000000",
            "--relative-density",
            "0.5",
            "--calibration-runs",
            "0",
            "--void-ratio-limits",
            "0.9,1.8",
            "--refine-runs",
            "1",
            "--journal",
            journal.to_str().unwrap(),
        ])
        .collect();
    let whole = run("pack", &args, &nine);
    assert!(
        whole.status.success(),
        "pack failed: {}",
        String::from_utf8_lossy(&whole.stderr)
    );
    let text = std::fs::read_to_string(&journal).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines.len(),
        3,
        "the limits' two and the refinement's: {text}"
    );
    let stopped = format!(
        "{}\n{}\n{}",
        lines[0],
        lines[1],
        &lines[2][..lines[2].len() / 2]
    );
    std::fs::write(&journal, &stopped).unwrap();
    let again = run_env("pack", &args, &nine, &[("GRANULAR_PROGRESS_SECONDS", "0")]);
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(again.status.success(), "pack failed: {err}");
    assert_eq!(err.matches("taken from the journal").count(), 2, "{err}");
    assert!(err.contains("run 3 of 4 (refinement"), "{err}");
    assert!(whole.stdout == again.stdout, "the resumed specimen differs");
    // The cut line went and the refinement's came back whole.
    assert_eq!(std::fs::read_to_string(&journal).unwrap(), text);
    // All three from the journal: only the specimen is compacted.
    let third = run("pack", &args, &nine);
    let err = String::from_utf8_lossy(&third.stderr);
    assert_eq!(err.matches("taken from the journal").count(), 3, "{err}");
    assert!(
        whole.stdout == third.stdout,
        "the specimen from the journal differs"
    );
    // A line in the middle that is not a compaction is refused, with its number.
    std::fs::write(&journal, format!("{}\nnot json\n{}\n", lines[0], lines[1])).unwrap();
    rejects(
        &args,
        &nine,
        1,
        &["--journal", "journal line 2 is not a compaction"],
    );
    // A run refused before any compaction leaves no journal behind.
    let fresh = dir.join("never.journal");
    let bad: Vec<&str> = (SOFT.iter().copied())
        .chain([
            "--relative-density",
            "1.5",
            "--journal",
            fresh.to_str().unwrap(),
        ])
        .collect();
    rejects(&bad, &nine, 2, &["--relative-density must be in [0, 1]"]);
    assert!(!fresh.exists(), "a refused run left {}", fresh.display());
    std::fs::remove_dir_all(&dir).ok();
}
