//! The dem tool: restart equality, thread determinism, bad scenes.

use super::{fixture, inside_out_cube, ok, repo_file, run, run_env};

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

/// 80 cubes of 20 mm in 16 touching columns of 5 on a floor, at their equilibrium overlaps,
/// neighbouring columns overlapping by 1 nm: above the parallel threshold, about 200 contacts.
fn column_bed() -> Vec<u8> {
    let mut lines = vec![
        r#"{"type":"header","format":"granular-dem","version":1,"units":"SI"}"#.to_string(),
        r#"{"type":"material","density":2600,"kn":1e8,"ks":5e7,"friction":0.5,"wall_friction":0.0,"damping":0.3}"#.to_string(),
        r#"{"type":"clock","time":0,"step":0,"dt":0,"gravity":[0,0,-9.81]}"#.to_string(),
        r#"{"type":"shape","id":0,"name":"cube","vertices":[[-0.5,-0.5,-0.5],[0.5,-0.5,-0.5],[-0.5,0.5,-0.5],[0.5,0.5,-0.5],[-0.5,-0.5,0.5],[0.5,-0.5,0.5],[-0.5,0.5,0.5],[0.5,0.5,0.5]],"faces":[[0,2,3,1],[4,5,7,6],[0,1,5,4],[2,6,7,3],[0,4,6,2],[1,3,7,5]]}"#.to_string(),
        r#"{"type":"wall","id":0,"kind":"plane","normal":[0,0,1],"offset":0}"#.to_string(),
    ];
    let (side, weight) = (0.02f64, 2600.0 * shared::math::cube(0.02f64) * 9.81);
    let mut id = 0;
    for i in 0..4 {
        for j in 0..4 {
            let mut z = 0.0;
            for level in 0..5 {
                z -= (5 - level) as f64 * weight / 1e8;
                let (x, y) = (i as f64 * (side - 1e-9), j as f64 * (side - 1e-9));
                lines.push(format!(
                    r#"{{"type":"body","id":{id},"shape":0,"scale":0.02,"pos":[{x},{y},{}]}}"#,
                    z + side / 2.0
                ));
                z += side;
                id += 1;
            }
        }
    }
    (lines.join("\n") + "\n").into_bytes()
}

#[test]
fn same_bytes_for_one_and_two_threads() {
    let scene = column_bed();
    // The lateral contacts push the columns apart within tens of steps; the first steps are
    // the contact-rich ones.
    let first = ok("dem", &["--steps", "1"], &scene);
    let contacts = String::from_utf8_lossy(&first)
        .matches("\"type\":\"contact\"")
        .count();
    assert!(
        contacts > 150,
        "the column bed starts with many contacts: {contacts}"
    );
    let one = run_env(
        "dem",
        &["--steps", "300"],
        &scene,
        &[("RAYON_NUM_THREADS", "1")],
    );
    let two = run_env(
        "dem",
        &["--steps", "300"],
        &scene,
        &[("RAYON_NUM_THREADS", "2")],
    );
    assert!(
        one.status.success(),
        "{}",
        String::from_utf8_lossy(&one.stderr)
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
    // Usage errors (exit code 2): options out of their range or missing.
    for (args, needle) in [
        (&[][..], "--steps N or --time T"),
        (&["--steps", "1", "--dt", "-1"][..], "--dt"),
        (
            &["--steps", "1", "--until-unbalanced", "0"][..],
            "--until-unbalanced must be a positive ratio",
        ),
        (&["--until-unbalanced", "0.01"][..], "--steps N or --time T"),
        (
            &["--steps", "1", "--kn", "0"][..],
            "--kn must be a positive",
        ),
        (
            &["--steps", "1", "--ks", "nan"][..],
            "--ks must be a stiffness of 0 or more",
        ),
        (
            &["--steps", "1", "--damping", "1"][..],
            "--damping must be in [0, 1)",
        ),
        (&["--abrade", "5", "--steps", "1"][..], "'5' for '--abrade"),
        (&["--abrade", "x", "--steps", "1"][..], "'x' for '--abrade"),
        (
            &["--simplify", "3", "--steps", "1"][..],
            "'3' for '--simplify",
        ),
    ] {
        let out = run("dem", args, &scene);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(needle), "expected '{needle}' in: {err}");
        assert!(out.stdout.is_empty());
    }
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

#[test]
fn until_unbalanced_stops_early_at_the_ratio() {
    // The six polyhedra of the example settle on the floor: the run stops well before the
    // 2 s limit, with the ratio of its last step below the target.
    let scene = repo_file("examples/drop.jsonl");
    let series = std::env::temp_dir().join(format!("dem-until-{}.jsonl", std::process::id()));
    let out = run(
        "dem",
        &[
            "--until-unbalanced",
            "0.01",
            "--time",
            "2",
            "--series",
            series.to_str().unwrap(),
            "--every",
            "1000000000",
        ],
        &scene,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("unbalanced-force ratio") && err.contains("< 0.01"),
        "{err}"
    );
    let text = std::fs::read_to_string(&series).unwrap();
    let _ = std::fs::remove_file(&series);
    let last: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    let (time, ratio) = (
        last["time"].as_f64().unwrap(),
        last["unbalanced"].as_f64().unwrap(),
    );
    assert!(ratio < 0.01, "ratio {ratio}");
    assert!(time < 1.9, "stopped at {time} s");
    // And the state it wrote is that step's.
    let state = String::from_utf8(out.stdout).unwrap();
    assert!(
        state.contains(&format!("\"step\":{}", last["step"])),
        "state at the last step"
    );
}

#[test]
fn renumber_orders_the_bodies_along_space_and_keeps_the_scene() {
    // The column bed's ids go up each column in turn; after a step it has ~200 contacts.
    let state = ok("dem", &["--steps", "1"], &column_bed());
    let sorted = ok("dem", &["--renumber", "--steps", "0"], &state);
    let records = |s: &[u8], kind: &str| -> Vec<serde_json::Value> {
        String::from_utf8_lossy(s)
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .filter(|v| v["type"] == kind)
            .collect()
    };
    let (before, after) = (records(&state, "body"), records(&sorted, "body"));
    assert_eq!(before.len(), after.len());
    assert_ne!(before, after, "the column order is not the curve's");
    // The same bodies (positions), in another order.
    let key = |b: &serde_json::Value| b["pos"].to_string();
    let mut a: Vec<String> = before.iter().map(key).collect();
    let mut b: Vec<String> = after.iter().map(key).collect();
    a.sort();
    b.sort();
    assert_eq!(a, b);
    assert_eq!(
        records(&state, "contact").len(),
        records(&sorted, "contact").len()
    );
    // Ordered already: a second renumbering writes the same bytes.
    assert_eq!(ok("dem", &["--renumber", "--steps", "0"], &sorted), sorted);
    // And the renumbered scene runs.
    let later = ok("dem", &["--steps", "50"], &sorted);
    assert!(String::from_utf8_lossy(&later).contains("\"step\":51"));
}

#[test]
fn abrade_turns_a_scene_into_its_ab_k_hulls() {
    let scene = repo_file("examples/drop.jsonl");
    let vertices = |state: &[u8]| -> Vec<usize> {
        String::from_utf8_lossy(state)
            .lines()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
            .filter(|v| v["type"] == "shape")
            .map(|v| v["vertices"].as_array().unwrap().len())
            .collect()
    };
    let sharp = vertices(&ok("dem", &["--steps", "0"], &scene));
    let smooth = vertices(&ok("dem", &["--abrade", "2", "--steps", "0"], &scene));
    assert!(!sharp.is_empty() && sharp.len() == smooth.len());
    for (a, b) in sharp.iter().zip(&smooth) {
        assert!(*b > 4 * a, "{a} vertices abraded twice gave {b}");
    }
    // Cut to a vertex budget: each abraded shape keeps at most that many vertices.
    let cut = vertices(&ok(
        "dem",
        &["--abrade", "2", "--simplify", "40", "--steps", "0"],
        &scene,
    ));
    assert!(cut.iter().all(|&n| n <= 40) && cut.contains(&40), "{cut:?}");
    // The abraded scene runs.
    let state = ok("dem", &["--abrade", "1", "--steps", "200"], &scene);
    assert!(String::from_utf8_lossy(&state).contains("\"step\":200"));
}

/// A peer scene of three particles (tetrahedra 10, 20 and 30 mm across) in a box.
const PEER_SCENE: &str = "# peer-scene v1\nbox 0.2 0.2 0.2\n\
    0 4 0.01 0.05 0.05 0.05 4 0.01 0 0 0 0.01 0 0 0 0.01 -0.005 -0.005 -0.005\n\
    1 4 0.02 0.15 0.05 0.05 4 0.02 0 0 0 0.02 0 0 0 0.02 -0.01 -0.01 -0.01\n\
    2 4 0.03 0.05 0.15 0.05 4 0.03 0 0 0 0.03 0 0 0 0.03 -0.015 -0.015 -0.015\n";

/// A file in the temporary directory that is removed when the test lets go of it, passed or
/// failed, so test runs leave nothing behind.
struct TempFile(std::path::PathBuf);

impl std::ops::Deref for TempFile {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn temp_file(name: &str, text: &[u8]) -> TempFile {
    let path = std::env::temp_dir().join(format!("dem-{}-{name}", std::process::id()));
    std::fs::write(&path, text).unwrap();
    TempFile(path)
}

#[test]
fn peer_scenes_take_shared_templates() {
    let scene = temp_file("peer.txt", PEER_SCENE.as_bytes());
    let templates = temp_file("nine.obj", &fixture("templates_seed7.obj"));
    let (scene, templates) = (scene.to_str().unwrap(), templates.to_str().unwrap());
    let own = String::from_utf8(ok("dem", &["--import-peer", scene, "--steps", "0"], b"")).unwrap();
    let shared = String::from_utf8(ok(
        "dem",
        &[
            "--import-peer",
            scene,
            "--templates",
            templates,
            "--steps",
            "0",
        ],
        b"",
    ))
    .unwrap();
    let shapes = |s: &str| {
        s.lines()
            .filter(|l| l.contains("\"type\":\"shape\""))
            .count()
    };
    assert_eq!(shapes(&own), 3, "one shape per particle");
    assert_eq!(shapes(&shared), 9, "the nine templates, shared");
    assert!(shared.contains("\"shape\":2,"), "particle 2 is template 2");
    // Bad templates: none, a flat object, and the flag without a peer scene.
    let empty = temp_file("empty.obj", b"# nothing\n");
    fails(
        &[
            "--import-peer",
            scene,
            "--templates",
            empty.to_str().unwrap(),
            "--steps",
            "0",
        ],
        b"",
        &["no objects"],
    );
    let flat = temp_file(
        "flat.obj",
        b"o flat\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\nf 3 4 2 1\n",
    );
    fails(
        &[
            "--import-peer",
            scene,
            "--templates",
            flat.to_str().unwrap(),
            "--steps",
            "0",
        ],
        b"",
        &["'flat'", "line 1", "encloses no volume"],
    );
    // An open mesh and an inside-out one are not solids: named, with the line.
    let open = temp_file(
        "open.obj",
        b"o open\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n",
    );
    let inside_out = temp_file("inside-out.obj", &inside_out_cube());
    for (file, needles) in [
        (&open, ["'open'", "boundary edge"]),
        (&inside_out, ["'cube'", "point inwards"]),
    ] {
        let path = file.to_str().unwrap();
        let args = ["--import-peer", scene, "--templates", path, "--steps", "0"];
        let mut all = vec![path];
        all.extend(needles);
        fails(&args, b"", &all);
    }
    let out = run("dem", &["--templates", templates, "--steps", "0"], b"");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--import-peer"));
}

#[test]
fn obj_output_holds_the_bodies_where_they_are_and_renders() {
    let scene = repo_file("examples/drop.jsonl");
    let path = std::env::temp_dir().join(format!("dem-obj-{}.obj", std::process::id()));
    let state = ok(
        "dem",
        &[
            "--steps",
            "2000",
            "--obj",
            path.to_str().unwrap(),
            "--obj-group",
            "drop",
        ],
        &scene,
    );
    let obj = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    let objects = shared::geometry::obj::read_all(&obj[..]).unwrap();
    let bodies: Vec<serde_json::Value> = String::from_utf8(state)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["type"] == "body")
        .collect();
    assert_eq!(objects.len(), bodies.len());
    for (o, b) in objects.iter().zip(&bodies) {
        assert_eq!(o.mesh.name, format!("drop/{}", b["id"]));
        assert!(o.mesh.attrs.get("color").is_some());
        // Each object is its body's hull where the state has it: same centroid, and turned
        // as the body is, its inertia diagonal in the body's axes.
        let m = shared::geometry::mass::MassProps::of(&o.mesh);
        for k in 0..3 {
            let x = b["pos"][k].as_f64().unwrap();
            assert!(
                (m.centroid[k] - x).abs() < 1e-9,
                "centroid {:?} against {}",
                m.centroid,
                b["pos"]
            );
        }
        let q = |k: usize| b["rot"][k].as_f64().unwrap();
        let (w, x, y, z) = (q(0), q(1), q(2), q(3));
        let r = shared::math::Mat3::new(
            1.0 - 2.0 * (y * y + z * z),
            2.0 * (x * y - w * z),
            2.0 * (x * z + w * y),
            2.0 * (x * y + w * z),
            1.0 - 2.0 * (x * x + z * z),
            2.0 * (y * z - w * x),
            2.0 * (x * z - w * y),
            2.0 * (y * z + w * x),
            1.0 - 2.0 * (x * x + y * y),
        );
        let body = r.transpose() * m.inertia * r;
        let off = body[(0, 1)].abs() + body[(0, 2)].abs() + body[(1, 2)].abs();
        assert!(off < 1e-6 * body.trace(), "{body}");
    }
    let png = ok("render", &[], &obj);
    assert!(png.starts_with(b"\x89PNG"));
    super::fails(
        "dem",
        &["--steps", "1", "--obj", "x.obj", "--obj-group", "a b"],
        &scene,
        2,
        &["--obj-group must be a word"],
    );
}
