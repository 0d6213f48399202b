//! The dem tool: restart equality, thread determinism, bad scenes.

use super::{ok, repo_file, run, run_env};

#[test]
fn restart_equals_the_uninterrupted_run_byte_for_byte() {
    let scene = repo_file("examples/drop.jsonl");
    let half = ok("dem", &["--steps", "600000"], &scene);
    // The split falls while a body rests on the floor: its contact and shear spring cross it.
    assert!(
        String::from_utf8_lossy(&half).contains("\"type\":\"contact\""),
        "a contact at the split"
    );
    let twice = ok("dem", &["--steps", "600000"], &half);
    let whole = ok("dem", &["--steps", "1200000"], &scene);
    assert_eq!(twice, whole);
}

/// The peer benchmark's settled 500-particle bed (beside the repository, as CI has it): well
/// above the parallel threshold, with about 1400 contacts from the first step.
fn peer_bed_args() -> Vec<String> {
    let peers = format!("{}/../shared/peers/yade", env!("CARGO_MANIFEST_DIR"));
    assert!(
        std::path::Path::new(&peers).is_dir(),
        "the handout's peers/yade must be beside the repository"
    );
    vec![
        "--import-peer".into(),
        format!("{peers}/scene_500.txt"),
        "--peer-state".into(),
        format!("{peers}/settled_500_state.txt"),
        "--steps".into(),
        "20".into(),
    ]
}

#[test]
fn same_bytes_for_one_and_two_threads() {
    let args = peer_bed_args();
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let one = run_env("dem", &args, b"", &[("RAYON_NUM_THREADS", "1")]);
    let two = run_env("dem", &args, b"", &[("RAYON_NUM_THREADS", "2")]);
    assert!(
        one.status.success(),
        "{}",
        String::from_utf8_lossy(&one.stderr)
    );
    let contacts = String::from_utf8_lossy(&one.stdout)
        .matches("\"type\":\"contact\"")
        .count();
    assert!(
        contacts > 1000,
        "the settled bed has many contacts: {contacts}"
    );
    assert_eq!(one.stdout, two.stdout);
}

#[test]
fn the_energy_audit_closes_on_the_example() {
    let dir = std::env::temp_dir().join(format!("dem-series-{}", std::process::id()));
    let path = dir.with_extension("jsonl");
    ok(
        "dem",
        &[
            "--time",
            "0.2",
            "--every",
            "1000",
            "--series",
            path.to_str().unwrap(),
        ],
        &repo_file("examples/drop.jsonl"),
    );
    let text = std::fs::read_to_string(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let last: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    let (balance, work) = (
        last["balance"].as_f64().unwrap(),
        last["gravity_work"].as_f64().unwrap(),
    );
    // Measured: the audit closes to 0.7 % of the work gravity did (the rest is the
    // non-conservative lifted-edge contact, see the known failures in shared/tests/dem_physics.rs).
    assert!(
        work > 0.0 && balance.abs() < 0.01 * work,
        "balance {balance} vs gravity work {work}"
    );
}

fn fails(args: &[&str], stdin: &[u8], needles: &[&str]) {
    let out = run("dem", args, stdin);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    for n in needles {
        assert!(err.contains(n), "expected '{n}' in: {err}");
    }
    assert!(out.stdout.is_empty(), "nothing written on error");
}

#[test]
fn bad_scenes_and_arguments() {
    let scene = repo_file("examples/drop.jsonl");
    let text = String::from_utf8(scene.clone()).unwrap();
    fails(
        &["--steps", "1"],
        text.replace("\"version\":1", "\"version\":2").as_bytes(),
        &["dem: line 1: version 2"],
    );
    fails(&["--steps", "1"], &scene[..scene.len() - 30], &["line 16"]);
    fails(&["--steps", "1"], b"", &["empty"]);
    fails(&[], &scene, &["--steps N or --time T"]);
    fails(&["--steps", "1", "--dt", "-1"], &scene, &["--dt"]);
    fails(
        &["--steps", "1"],
        text.replace("\"scale\":0.008", "\"scale\":-1").as_bytes(),
        &["line 11", "scale"],
    );
    fails(
        &["--import-peer", "/nonexistent/scene.txt", "--steps", "1"],
        b"",
        &["opening /nonexistent/scene.txt"],
    );
}

#[test]
fn vtk_snapshots_and_collections() {
    let dir = std::env::temp_dir().join(format!("dem-vtk-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    ok(
        "dem",
        &[
            "--steps",
            "3000",
            "--vtk",
            dir.to_str().unwrap(),
            "--vtk-every",
            "1000",
        ],
        &repo_file("examples/drop.jsonl"),
    );
    for stream in ["particles", "contacts", "walls"] {
        let pvd = std::fs::read_to_string(dir.join(format!("{stream}.pvd"))).unwrap();
        // One snapshot at the start and one every 1000 steps: 4 in all.
        assert_eq!(pvd.matches("<DataSet").count(), 4, "{pvd}");
        for k in 0..4 {
            let vtu = std::fs::read_to_string(dir.join(format!("{stream}_{k:06}.vtu"))).unwrap();
            assert!(vtu.starts_with("<?xml") && vtu.trim_end().ends_with("</VTKFile>"));
        }
    }
    let p = std::fs::read_to_string(dir.join("particles_000000.vtu")).unwrap();
    assert!(p.contains("Name=\"id\"") && p.contains("Name=\"velocity\""));
    let _ = std::fs::remove_dir_all(&dir);
}
