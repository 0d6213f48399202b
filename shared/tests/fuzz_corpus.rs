//! Every input the fuzzers keep (`fuzz/seeds`, the minimised `fuzz/corpus` and each crash they
//! found, `fuzz/regressions`), replayed through the same entry points (`shared::fuzz`) on the
//! stable toolchain: a crash once fixed stays fixed. An input that panics fails its target's
//! test with the file's name.

use std::path::{Path, PathBuf};

fn inputs(target: &str) -> Vec<PathBuf> {
    let fuzz = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz");
    let mut files = Vec::new();
    for kind in ["seeds", "corpus", "regressions"] {
        let Ok(dir) = std::fs::read_dir(fuzz.join(kind).join(target)) else {
            continue;
        };
        files.extend(dir.filter_map(|e| e.ok()).map(|e| e.path()));
    }
    files.sort();
    files
}

fn replay(target: &str, run: fn(&[u8])) {
    let files = inputs(target);
    assert!(!files.is_empty(), "no inputs kept for {target}");
    for f in &files {
        let data = std::fs::read(f).unwrap();
        let outcome = std::panic::catch_unwind(|| run(&data));
        assert!(outcome.is_ok(), "{target} panicked on {}", f.display());
    }
    eprintln!("{target}: {} inputs", files.len());
}

#[test]
fn obj_stream_inputs_are_read_or_refused() {
    replay("obj_stream", shared::fuzz::obj_stream);
}

#[test]
fn dem_state_inputs_are_read_or_refused() {
    replay("dem_state", shared::fuzz::dem_state);
}

#[test]
fn peer_scene_inputs_are_read_or_refused() {
    replay("peer_scene", shared::fuzz::peer_scene);
}

#[test]
fn plot_csv_inputs_are_drawn_or_refused() {
    replay("plot_csv", shared::fuzz::plot_csv);
}
