//! What the fuzzers feed (`fuzz/`, `pipelines/fuzz.sh`), one function per reader: each takes
//! any bytes, reads them as the tools do and goes on as far as the tools would with what it
//! read. None may panic, hang or allocate without bound; errors are the expected answer. The
//! same functions replay the kept corpus and every crash found in the test suite
//! (`shared/tests/fuzz_corpus.rs`), so a fixed crash stays fixed without a fuzzer installed.

use crate::dem::io::{state, yade};
use crate::dem::shape::Shape;
use crate::draw::plot;
use crate::geometry::mesh::cube;
use crate::geometry::obj;
use std::sync::OnceLock;

/// The OBJ stream: every object read, then made a shape as `dem` and `pack` make one.
pub fn obj_stream(data: &[u8]) {
    if let Ok(objects) = obj::read_all(data) {
        for o in &objects {
            let _ = Shape::from_mesh(&o.mesh);
        }
    }
}

/// A dem scene or state: read, then its time step computed (what every run does first).
pub fn dem_state(data: &[u8]) {
    if let Ok(world) = state::read_world(data) {
        let _ = world.time_step(0.2);
    }
}

/// A peer (Yade) scene: the first line of the bytes up to a NUL the box and particles, what
/// follows the NUL (if any) the settled state; a cube as the one template.
pub fn peer_scene(data: &[u8]) {
    let (scene, settled) = match data.iter().position(|&b| b == 0) {
        Some(k) => (&data[..k], Some(&data[k + 1..])),
        None => (data, None),
    };
    let _ = yade::read_peer_scene(scene, settled, Some(std::slice::from_ref(cube_shape())));
    let _ = yade::read_peer_scene(scene, settled, None);
}

/// A CSV table for `plot`: its first two columns as x and y, grouped by a third when there is
/// one, drawn small (the axes' ranges and ticks are what arbitrary numbers stress).
pub fn plot_csv(data: &[u8]) {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .from_reader(data);
    let mut rows = Vec::new();
    for record in reader.records().take(10_000) {
        let Ok(r) = record else { break };
        let num = |i: usize| r.get(i).and_then(|s| s.trim().parse::<f64>().ok());
        if let (Some(x), Some(y)) = (num(0), num(1)) {
            rows.push((r.get(2).unwrap_or("").to_string(), x, y));
        }
    }
    if rows.is_empty() {
        return;
    }
    let points = rows.iter().map(|&(_, x, y)| (x, y)).collect();
    let band = plot::group_stats(&rows)
        .into_values()
        .flatten()
        .map(|(x, s)| (x, s.min, s.max))
        .collect();
    let chart = plot::Chart {
        title: "fuzz".into(),
        xlabel: "x".into(),
        ylabel: "y".into(),
        series: vec![plot::Series {
            label: "y".into(),
            points,
            band,
            color: 0,
            dashed: false,
        }],
    };
    let _ = plot::draw(&chart, 160, 120);
}

/// The peer scene's one template: the project's cube, made once for all inputs.
fn cube_shape() -> &'static Shape {
    static CUBE: OnceLock<Shape> = OnceLock::new();
    CUBE.get_or_init(|| Shape::from_mesh(&cube(1.0)).expect("a cube's shape"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_entry_takes_good_and_broken_input() {
        let cube = obj::to_string(&[cube(1.0)]);
        assert_eq!(cube_shape().vertices.len(), 8);
        for data in [
            cube.as_bytes(),
            b"",
            b"\xff\xfe",
            b"f 1 2 3\n",
            b"v 1e308 0 0\n",
        ] {
            obj_stream(data);
            dem_state(data);
            peer_scene(data);
            plot_csv(data);
        }
        plot_csv(b"x,y\n1e308,0\n-1e308,1\nnan,2\n");
    }
}
