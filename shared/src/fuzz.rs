//! What the fuzzers feed (`fuzz/`, `pipelines/fuzz.sh`), one function per reader: each takes
//! any bytes, reads them as the tools do and goes on as far as the tools would with what it
//! read. None may panic, hang or allocate without bound; errors are the expected answer. The
//! same functions replay the kept corpus and every crash found in the test suite
//! (`shared/tests/fuzz_corpus.rs`), so a fixed crash stays fixed without a fuzzer installed.

use crate::dem::io::{state, yade};
use crate::dem::shape::Shape;
use crate::draw::plot;
use crate::geometry::obj;

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
    let cube = cube_shape();
    let _ = yade::read_peer_scene(scene, settled, Some(std::slice::from_ref(&cube)));
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

fn cube_shape() -> Shape {
    let corners = [
        [-1.0, -1.0, -1.0],
        [1.0, -1.0, -1.0],
        [1.0, 1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
        [1.0, -1.0, 1.0],
        [1.0, 1.0, 1.0],
        [-1.0, 1.0, 1.0],
    ];
    let mut text = String::new();
    for c in corners {
        text += &format!("v {} {} {}\n", c[0], c[1], c[2]);
    }
    text += "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    let objects = obj::read_all(text.as_bytes()).expect("a cube");
    Shape::from_mesh(&objects[0].mesh).expect("a cube's shape")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_entry_takes_good_and_broken_input() {
        let cube = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n\
                    f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
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
