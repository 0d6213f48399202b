//! End-to-end tests: the real binaries, fed through pipes.

mod bad_input;
mod cluster;
mod dem;
mod fabric;
mod pack;
mod pipes;
mod triax;

use std::io::Write;
use std::process::{Command, Output, Stdio};

/// Runs a tool with arguments and standard input; returns its output.
pub fn run(tool: &str, args: &[&str], stdin: &[u8]) -> Output {
    run_env(tool, args, stdin, &[])
}

/// Like `run`, with extra environment variables.
pub fn run_env(tool: &str, args: &[&str], stdin: &[u8], env: &[(&str, &str)]) -> Output {
    run_env_without(tool, args, stdin, env, &[])
}

/// Like `run_env`, with the variables `remove` taken out of the environment.
pub fn run_env_without(
    tool: &str,
    args: &[&str],
    stdin: &[u8],
    env: &[(&str, &str)],
    remove: &[&str],
) -> Output {
    let exe = match tool {
        "polygen" => env!("CARGO_BIN_EXE_polygen"),
        "abrade" => env!("CARGO_BIN_EXE_abrade"),
        "roundness" => env!("CARGO_BIN_EXE_roundness"),
        "render" => env!("CARGO_BIN_EXE_render"),
        "simplify" => env!("CARGO_BIN_EXE_simplify"),
        "plot" => env!("CARGO_BIN_EXE_plot"),
        "dem" => env!("CARGO_BIN_EXE_dem"),
        "pack" => env!("CARGO_BIN_EXE_pack"),
        "triax" => env!("CARGO_BIN_EXE_triax"),
        "fabric" => env!("CARGO_BIN_EXE_fabric"),
        other => panic!("no tool {other}"),
    };
    let mut command = Command::new(exe);
    // What changes a tool's messages comes from the test alone (`make test` sets a tag).
    for r in remove
        .iter()
        .chain(&["GRANULAR_TAG", "GRANULAR_PROGRESS_SECONDS"])
    {
        command.env_remove(r);
    }
    let mut child = command
        .args(args)
        .envs(env.iter().copied())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("tool starts");
    let mut input = child.stdin.take().expect("stdin");
    let data = stdin.to_vec();
    let writer = std::thread::spawn(move || {
        let _ = input.write_all(&data);
    });
    let out = child.wait_with_output().expect("tool finishes");
    writer.join().expect("writer thread");
    out
}

/// Runs a tool on bad input; checks exit code and that stderr holds every `needles` entry.
pub fn fails(tool: &str, args: &[&str], stdin: &[u8], code: i32, needles: &[&str]) -> Vec<u8> {
    let out = run(tool, args, stdin);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(code),
        "{tool} {args:?}: stderr {err}"
    );
    assert!(
        err.starts_with(&format!("{tool}: ")) || code == 2,
        "message names the tool: {err}"
    );
    for n in needles {
        assert!(err.contains(n), "{tool} {args:?}: expected '{n}' in: {err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    out.stdout
}

/// Runs and requires success; returns standard output.
pub fn ok(tool: &str, args: &[&str], stdin: &[u8]) -> Vec<u8> {
    let out = run(tool, args, stdin);
    assert!(
        out.status.success(),
        "{tool} {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out.stdout
}

/// Text of a file of the repository.
pub fn repo_file(path: &str) -> Vec<u8> {
    std::fs::read(format!("{}/{path}", env!("CARGO_MANIFEST_DIR"))).expect("file exists")
}

/// Text of the fixture file `name`.
pub fn fixture(name: &str) -> Vec<u8> {
    std::fs::read(format!(
        "{}/tests/fixtures/{name}",
        env!("CARGO_MANIFEST_DIR")
    ))
    .expect("fixture exists")
}

/// The fixture cube with every face turned inside out.
pub fn inside_out_cube() -> Vec<u8> {
    let text = String::from_utf8(fixture("cube.obj")).unwrap();
    text.lines()
        .map(|l| match l.strip_prefix("f ") {
            Some(f) => format!("f {}\n", f.split(' ').rev().collect::<Vec<_>>().join(" ")),
            None => format!("{l}\n"),
        })
        .collect::<String>()
        .into_bytes()
}
