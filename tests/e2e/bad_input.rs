//! Broken input: every tool must say what is wrong (naming object and line where there is one),
//! exit non-zero, and never write half an object.

use super::{fails, fixture, ok};

/// A good cube followed by `bad` (an object text using indices that follow the cube's 8).
fn after_a_good_cube(bad: &str) -> Vec<u8> {
    let mut s = fixture("cube.obj");
    s.extend_from_slice(bad.as_bytes());
    s
}

const TET_VERTS: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n";

#[test]
fn abrade_rejects_each_kind_of_broken_mesh() {
    let cases: &[(&str, String, &[&str])] = &[
        ("open", format!("o open\n{TET_VERTS}f 9 11 10\nf 9 10 12\nf 9 12 11\n"), &["'open'", "line 17", "(line 2", "boundary edge"]),
        ("flipped", format!("o flipped\n{TET_VERTS}f 9 11 10\nf 9 10 12\nf 9 12 11\nf 10 12 11\n"), &["'flipped'", "line 17", "flipped"]),
        ("three faces on an edge", format!("o fin\n{TET_VERTS}v 1 1 1\nf 9 11 10\nf 9 10 12\nf 9 12 11\nf 10 11 12\nf 9 10 13\n"), &["'fin'", "shared by 3 faces"]),
        ("repeated vertex", format!("o deg\n{TET_VERTS}f 9 11 10\nf 9 10 12\nf 9 12 11\nf 10 11 12 12\n"), &["'deg'", "face 4 (line 25)", "distinct vertices"]),
        ("index out of range", format!("o far\n{TET_VERTS}f 9 11 99\n"), &["'far'", "line 22", "out of range"]),
        ("nan", "o nan\nv 0 0 0\nv 1 nan 0\n".to_string(), &["'nan'", "line 19", "not finite"]),
        ("garbage", "o junk\nv 0 0 0\nhello world\n".to_string(), &["'junk'", "line 19", "unknown OBJ statement"]),
        ("two-corner face", format!("o two\n{TET_VERTS}f 9 10\n"), &["'two'", "2 corners"]),
        ("earlier object's vertex", format!("o thief\n{TET_VERTS}f 1 10 11\n"), &["'thief'", "earlier object"]),
    ];
    let good = ok("abrade", &[], &fixture("cube.obj"));
    for (what, text, needles) in cases {
        let out = fails("abrade", &[], &after_a_good_cube(text), 1, needles);
        // The good cube before it is written whole, nothing of the bad object.
        assert_eq!(
            out, good,
            "{what}: output must be exactly the good object before the bad one"
        );
    }
}

#[test]
fn empty_input_is_an_error() {
    for (tool, args) in [
        ("abrade", &[][..]),
        ("roundness", &[]),
        ("render", &[]),
        ("simplify", &["--vertices", "50"]),
    ] {
        fails(tool, args, b"", 1, &["no objects"]);
        fails(tool, args, b"# only a comment\n", 1, &["no objects"]);
    }
}

#[test]
fn simplify_rejects_broken_meshes_and_budgets() {
    // An open mesh (a cube missing a face) after a good cube: named, and the cube written.
    let open = "o open\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                f 9 12 11 10\nf 9 10 14 13\nf 10 11 15 14\nf 11 12 16 15\nf 12 9 13 16\n";
    let out = fails(
        "simplify",
        &["--vertices", "6"],
        &after_a_good_cube(open),
        1,
        &["'open'"],
    );
    assert_eq!(
        String::from_utf8_lossy(&out).matches("\no ").count(),
        1,
        "only the cube"
    );
    let flat = "o flat\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 4 3 2 1\n";
    fails(
        "simplify",
        &["--vertices", "6"],
        flat.as_bytes(),
        1,
        &["'flat'"],
    );
    fails(
        "simplify",
        &["--vertices", "3"],
        &fixture("cube.obj"),
        2,
        &["at least 4"],
    );
    fails("simplify", &[], &fixture("cube.obj"), 2, &["--vertices"]);
}

#[test]
fn roundness_rejects_inside_out_and_open_meshes() {
    let cube = String::from_utf8(fixture("cube.obj")).unwrap();
    let inside_out: String = cube
        .lines()
        .map(|l| {
            if let Some(f) = l.strip_prefix("f ") {
                format!("f {}", f.split(' ').rev().collect::<Vec<_>>().join(" "))
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    fails(
        "roundness",
        &[],
        inside_out.as_bytes(),
        1,
        &["'cube'", "inwards"],
    );
    fails(
        "roundness",
        &[],
        format!("o open\n{TET_VERTS}f 1 3 2\nf 1 2 4\n").as_bytes(),
        1,
        &["'open'", "boundary edge"],
    );
}

#[test]
fn roundness_rejects_a_flat_object() {
    // A closed but flat double-sided square: zero volume.
    let flat = "o flat\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\nf 4 3 2 1\n";
    fails(
        "roundness",
        &[],
        flat.as_bytes(),
        1,
        &["'flat'", "encloses no volume"],
    );
}

#[test]
fn bad_arguments_are_usage_errors() {
    fails("polygen", &["--faces", "9..6"], b"", 2, &["empty range"]);
    fails(
        "polygen",
        &["--faces", "six"],
        b"",
        2,
        &["not a whole number"],
    );
    fails("polygen", &["--bogus"], b"", 2, &["--bogus"]);
    fails(
        "abrade",
        &["--levels", "x"],
        b"",
        2,
        &["not a whole number"],
    );
    fails("render", &["--size", "10x10"], b"", 2, &["16 to 8192"]);
}

#[test]
fn bad_parameter_values_are_errors() {
    fails("polygen", &["--faces", "3"], b"", 2, &["at least 4 faces"]);
    fails("polygen", &["--radius", "-2"], b"", 2, &["radius"]);
    fails(
        "polygen",
        &["--max-elongation", "0.5"],
        b"",
        2,
        &["elongation cap"],
    );
    fails("polygen", &["--count", "0"], b"", 2, &["--count"]);
    fails(
        "polygen",
        &["--faces", "4", "--max-elongation", "2.5"],
        b"",
        1,
        &["raise --max-elongation"],
    );
    fails(
        "abrade",
        &["--levels", "9"],
        &fixture("cube.obj"),
        2,
        &["too many"],
    );
}

#[test]
fn plot_rejects_bad_tables() {
    fails(
        "plot",
        &["--x", "a", "--y", "nope"],
        b"a,b\n1,2\n",
        1,
        &["no column 'nope'"],
    );
    fails(
        "plot",
        &["--x", "a", "--y", "b"],
        b"a,b\n1,x\n",
        1,
        &["row 2", "'x'", "not a number"],
    );
    fails("plot", &["--x", "a", "--y", "b"], b"a,b\n", 1, &["no rows"]);
    fails(
        "plot",
        &["--x", "a", "--y", "b", "--band", "wide"],
        b"a,b\n1,2\n",
        2,
        &["--band"],
    );
}

#[test]
fn help_shows_an_example_pipe() {
    for tool in [
        "polygen",
        "abrade",
        "roundness",
        "render",
        "plot",
        "dem",
        "simplify",
    ] {
        let out = ok(tool, &["--help"], b"");
        let text = String::from_utf8(out).unwrap();
        assert!(
            text.contains("Examples:") && text.contains(" | "),
            "{tool} --help lacks an example pipe:\n{text}"
        );
    }
}

/// A time step that cannot be computed (a stiffness, density or size out of range) is an
/// input error, not a panic; a step above the critical one is warned about; a run that blows
/// up stops with the step and the body; a run that would never end is refused.
#[test]
fn dem_time_step_out_of_range_is_an_input_error_not_a_panic() {
    let drop = String::from_utf8(super::repo_file("examples/drop.jsonl")).unwrap();
    let tiny_density = drop.replace("\"density\":2600,", "\"density\":1e-300,");
    assert!(tiny_density != drop, "the scene's density is 2600");
    let tiny_body = drop.replacen("\"scale\":0.008", "\"scale\":1e-300", 1);
    assert!(tiny_body != drop, "the first body's scale is 0.008");
    for (args, scene) in [
        (&["--kn", "1e308", "--steps", "10"][..], &drop),
        (&["--steps", "3"][..], &tiny_density),
        (&["--steps", "3"][..], &tiny_body),
    ] {
        let out = fails("dem", args, scene.as_bytes(), 1, &["critical time step"]);
        assert!(out.is_empty(), "nothing written");
    }
    // A step of 1 s: warned about, and the blow-up it causes stops the run at its first step.
    let out = fails(
        "dem",
        &["--dt", "1", "--steps", "3"],
        drop.as_bytes(),
        1,
        &["above the critical", "blew up at step 1", "body 0"],
    );
    assert!(out.is_empty(), "no state written");
    // A body started 1 m below the floor is flung out at its first step: an error, not a state
    // of nulls.
    // 200 bodies in one spot: flung apart at the first step.
    let body = drop
        .lines()
        .find(|l| l.contains("\"type\":\"body\""))
        .unwrap();
    let mut spot: String = drop
        .lines()
        .filter(|l| !l.contains("\"type\":\"body\""))
        .map(|l| format!("{l}\n"))
        .collect();
    for i in 0..200 {
        spot.push_str(&body.replacen("\"id\":0,", &format!("\"id\":{i},"), 1));
        spot.push('\n');
    }
    fails(
        "dem",
        &["--steps", "10"],
        spot.as_bytes(),
        1,
        &["blew up at step", "no state written"],
    );
    let buried = drop.replacen("\"pos\":[0.0,0.0,0.04]", "\"pos\":[0.0,0.0,-1.0]", 1);
    assert!(buried != drop, "the first body's position");
    let out = fails(
        "dem",
        &["--steps", "100"],
        buried.as_bytes(),
        1,
        &["blew up at step 1", "body 0"],
    );
    assert!(out.is_empty(), "no state written");
    fails(
        "dem",
        &["--dt", "1e-300", "--time", "1"],
        drop.as_bytes(),
        2,
        &["more than 1e12"],
    );
}

/// Bodies started deep inside each other, too few to blow the run up, are flung apart by the
/// penalty law: the run goes on, with a warning naming the pair and the depth; a scene whose
/// bodies start apart gets no such warning.
#[test]
fn dem_warns_of_bodies_started_inside_each_other() {
    let drop = String::from_utf8(super::repo_file("examples/drop.jsonl")).unwrap();
    let mut spot = String::new();
    for line in drop.lines() {
        let line = match line.find("\"pos\":[") {
            Some(at) if line.contains("\"type\":\"body\"") => {
                let end = at + line[at..].find(']').unwrap();
                format!("{}\"pos\":[0,0,0.1{}", &line[..at], &line[end..])
            }
            _ => line.to_string(),
        };
        spot.push_str(&line);
        spot.push('\n');
    }
    assert_eq!(
        spot.matches("\"pos\":[0,0,0.1]").count(),
        6,
        "six bodies in one spot"
    );
    let out = super::run("dem", &["--steps", "10"], spot.as_bytes());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning: bodies 0 and 1 overlap by") && err.contains("flung apart"),
        "{err}"
    );
    let out = super::run("dem", &["--steps", "10"], drop.as_bytes());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && !err.contains("overlap"), "{err}");
}

/// The OBJ reader's messages: a byte-order mark is accepted; a vertex with extra values, a
/// repeated vertex, text that is not UTF-8, a NUL byte and a token of a million characters
/// each get a short message naming the line.
#[test]
fn obj_reader_messages_are_short_and_name_the_line() {
    let tetra = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    let with_bom = format!("\u{feff}{tetra}");
    super::ok("roundness", &[], with_bom.as_bytes());
    let weighted = tetra.replacen("v 0 0 0", "v 0 0 0 1", 1);
    super::ok("roundness", &[], weighted.as_bytes());
    fails(
        "roundness",
        &[],
        b"v 0 0 0 2\n",
        1,
        &["line 1", "more than x y z"],
    );
    fails(
        "roundness",
        &[],
        b"v 0 0 0 1 1 1\n",
        1,
        &["line 1", "more than x y z"],
    );
    let repeated = tetra.replace("f 1 3 2\n", "f 1 3 2 3\n");
    fails(
        "roundness",
        &[],
        repeated.as_bytes(),
        1,
        &["line 5", "repeats vertex 3"],
    );
    fails(
        "roundness",
        &[],
        b"v 0 0 0\n\xff\n",
        1,
        &["line 2", "not UTF-8"],
    );
    fails("roundness", &[], b"v 0\x00 0 0\n", 1, &["line 1", "\\u{0}"]);
    let mut long = b"v 0 0 ".to_vec();
    long.extend(std::iter::repeat_n(b'x', 1_000_000));
    long.push(b'\n');
    let out = super::run("roundness", &[], &long);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        out.stderr.len() < 200,
        "{} bytes of message",
        out.stderr.len()
    );
}

/// Requests no machine could serve are refused before any work (exit 2), angles that are not
/// numbers too, and a plot of values spanning more than a float ends with a message instead
/// of looping.
#[test]
fn impossible_requests_are_refused_before_the_work() {
    fails(
        "polygen",
        &["--faces", "4294967296"],
        b"",
        2,
        &["--max-faces"],
    );
    fails(
        "polygen",
        &["--faces", "6", "--count", "0"],
        b"",
        2,
        &["--count"],
    );
    fails("render", &["--azimuth", "nan"], b"", 2, &["--azimuth"]);
    // A level whose size is known before it is made: 1000 faces at level 6 are 6 million.
    let big = super::ok("polygen", &["--faces", "1000"], b"");
    fails(
        "abrade",
        &["--levels", "6"],
        &big,
        1,
        &["level 6 would have", "--max-faces"],
    );
    // A shape the engine would take gigabytes for: refused, pointing to simplify.
    let huge = super::ok(
        "polygen",
        &["--faces", "30000", "--max-elongation", "inf"],
        b"",
    );
    fails(
        "pack",
        &["--count", "10"],
        &huge,
        1,
        &["more than 50000", "simplify"],
    );
    fails("render", &["--elevation", "inf"], b"", 2, &["--elevation"]);
    fails(
        "plot",
        &["--x", "x", "--y", "y"],
        b"x,y\n0,1e308\n1,-1e308\n",
        1,
        &["more than a float can hold"],
    );
}

/// Numbers a tool's arithmetic cannot hold are refused on reading: a cube of 1e200 (whose hull
/// tests and inertia overflow) in every tool that reads meshes, and a pressure that would press
/// the particles into each other by more than their size.
#[test]
fn numbers_beyond_a_tools_arithmetic_are_refused_on_reading() {
    let cube = String::from_utf8(super::repo_file("tests/fixtures/cube.obj")).unwrap();
    let huge: String = cube
        .lines()
        .map(|l| match l.strip_prefix("v ") {
            Some(xyz) => {
                let big: Vec<String> = xyz
                    .split_whitespace()
                    .map(|c| format!("{}", c.parse::<f64>().unwrap() * 1e200))
                    .collect();
                format!("v {}\n", big.join(" "))
            }
            None => format!("{l}\n"),
        })
        .collect();
    for (tool, args) in [
        ("abrade", &["--levels", "1"][..]),
        ("simplify", &["--vertices", "6"][..]),
        ("roundness", &[][..]),
        ("render", &[][..]),
        ("pack", &["--count", "10"][..]),
    ] {
        fails(tool, args, huge.as_bytes(), 1, &["line", "beyond 1e50"]);
    }
    let templates = super::ok("polygen", &["--faces", "6..8", "--count", "3"], b"");
    fails(
        "pack",
        &["--pressure", "1e15", "--count", "20"],
        &templates,
        2,
        &["--pressure", "p d / kn"],
    );
}

/// A dem state says each thing once: a second material, clock or energy record, a second
/// contact of one pair, a negative clock time, an empty facets wall, a contact whose normal is
/// not a unit vector: each is an error naming its line.
#[test]
fn dem_refuses_repeated_and_empty_records() {
    let settled = super::ok(
        "dem",
        &["--time", "0.3"],
        &super::repo_file("examples/drop.jsonl"),
    );
    let text = String::from_utf8(settled).unwrap();
    let lines: Vec<String> = text.lines().map(String::from).collect();
    let find = |t: &str| {
        lines
            .iter()
            .position(|l| l.starts_with(&format!("{{\"type\":\"{t}\"")))
            .unwrap_or_else(|| panic!("a {t} record"))
    };
    let scene = |v: &[String]| v.join("\n") + "\n";
    let twice = |k: usize| {
        let mut v = lines.clone();
        v.insert(k + 1, lines[k].clone());
        scene(&v)
    };
    let edited = |k: usize, edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = lines.clone();
        let mut rec: serde_json::Value = serde_json::from_str(&lines[k]).unwrap();
        edit(&mut rec);
        v[k] = rec.to_string();
        scene(&v)
    };
    let (material, clock, energy, contact, wall) = (
        find("material"),
        find("clock"),
        find("energy"),
        find("contact"),
        find("wall"),
    );
    let cases = [
        (twice(material), material + 2, "a second material record"),
        (twice(clock), clock + 2, "a second clock record"),
        (twice(energy), energy + 2, "a second energy record"),
        (
            twice(contact),
            contact + 2,
            "a second contact of the same pair",
        ),
        (
            edited(clock, &|r| r["time"] = serde_json::json!(-1.0)),
            clock + 1,
            "time must not be negative",
        ),
        (
            edited(contact, &|r| {
                r["normal"][0] = serde_json::json!(r["normal"][0].as_f64().unwrap() + 0.5)
            }),
            contact + 1,
            "not a unit vector",
        ),
        (
            edited(
                wall,
                &|r| *r = serde_json::json!({"type": "wall", "id": 0, "kind": "facets", "nodes": [], "triangles": []}),
            ),
            wall + 1,
            "at least one triangle",
        ),
    ];
    for (input, line, what) in cases {
        fails(
            "dem",
            &["--steps", "1"],
            input.as_bytes(),
            1,
            &[what, &format!("line {line}")],
        );
    }
}

/// An output file into a folder that does not exist fails before the work, with nothing
/// written.
#[test]
fn outputs_into_missing_folders_fail_before_the_work() {
    let nine = fixture("templates_seed7.obj");
    let out = fails(
        "pack",
        &["--summary", "/nonexistent-dir/s.json"],
        &nine,
        1,
        &["/nonexistent-dir does not exist"],
    );
    assert!(out.is_empty());
    let drop = super::repo_file("examples/drop.jsonl");
    for flag in ["--obj", "--series"] {
        let out = fails(
            "dem",
            &["--steps", "10", flag, "/nonexistent-dir/x"],
            &drop,
            1,
            &["does not exist"],
        );
        assert!(out.is_empty());
    }
}

/// What one object may hold is bounded: a line of more than 16 MiB, more than 16 MiB of
/// comments or 10 000 attributes in one object are errors, quickly and in little memory.
#[test]
fn obj_reader_bounds_lines_comments_and_attributes() {
    let cube = String::from_utf8(fixture("cube.obj")).unwrap();
    let mut long = b"v 0 0 ".to_vec();
    long.resize(17 << 20, b'9');
    long.push(b'\n');
    fails(
        "roundness",
        &[],
        &long,
        1,
        &["line 1", "longer than 16777216 bytes"],
    );
    let comments = cube.clone() + &"# a comment of some length to fill the space\n".repeat(400_000);
    fails(
        "roundness",
        &[],
        comments.as_bytes(),
        1,
        &["bytes of comments in one object"],
    );
    let attributes: String = (0..10_001).map(|i| format!("#@ a{i}=1\n")).collect();
    fails(
        "roundness",
        &[],
        (cube + &attributes).as_bytes(),
        1,
        &["more than 10000 attributes"],
    );
}
