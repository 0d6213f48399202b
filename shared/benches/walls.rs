//! The price of a facet wall (the triaxial test's membrane and platens are facets): one settled
//! bed stepped with its box's four sides as planes, then as facets on the same planes (each side
//! a grid of `GRID` x `GRID` squares, two triangles each), side by side in alternating rounds.
//! Prints particle-steps per second for both, their ratio, and how far the side walls' forces
//! differ (the same contacts either way, to round-off). Run by `make bench` after
//! `pipelines/bench-dem.sh` has made the beds, or alone:
//!
//!     cargo bench -p granular-shared --bench walls -- out/bench/nine2000.jsonl [STEPS [GRID]]

use shared::dem::io::state::read_world;
use shared::dem::parallel::on_pool;
use shared::dem::wall::{grid_triangles, Wall, WallKind};
use shared::dem::world::World;
use shared::math::Vec3;
use std::time::Instant;

/// The four side planes of `w` (walls 1 to 4 of the bench beds) as facets: each side a grid of
/// `grid` x `grid` squares reaching past the box's edges (below the floor and beyond the other
/// sides, so that a body in a corner meets the same side as the plane's) and above the
/// highest body.
fn faceted(w: &World, grid: usize) -> Result<World, String> {
    let top = (w.bodies.iter()).map(|b| b.pos.z).fold(0.0f64, f64::max) * 1.5;
    if w.walls.len() < 5 {
        return Err(format!(
            "walls: the bed has {} walls, not a box's floor and four sides",
            w.walls.len()
        ));
    }
    let mut out = w.clone();
    for k in 1..=4 {
        let WallKind::Plane { normal, offset } = w.walls[k].kind else {
            return Err(format!("wall {k} is not a plane"));
        };
        // The side spans the other horizontal axis over the box (0 to the far wall's offset).
        let across = if normal.x != 0.0 { 1 } else { 0 };
        let far = (1..=4)
            .filter_map(|m| match w.walls[m].kind {
                WallKind::Plane { normal: n, offset } if n[across] < 0.0 => Some(-offset),
                _ => None,
            })
            .next()
            .ok_or("no far wall across the side")?;
        let on_plane = normal * offset;
        let node = |a: usize, h: usize| {
            let mut p = on_plane;
            p[across] = far * (1.2 * a as f64 / grid as f64 - 0.1);
            p.z = top * (1.1 * h as f64 / grid as f64 - 0.1);
            p
        };
        let nodes: Vec<Vec3> = (0..=grid)
            .flat_map(|h| (0..=grid).map(move |a| (a, h)))
            .map(|(a, h)| node(a, h))
            .collect();
        let mut triangles = grid_triangles(grid, grid);
        // Counter-clockwise seen from the particles' side: flip where the normal disagrees.
        let [a, b, c] = triangles[0].map(|i| nodes[i as usize]);
        if (b - a).cross(&(c - a)).dot(&normal) < 0.0 {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        out.walls[k] = Wall::facets(nodes, triangles);
    }
    Ok(out)
}

/// Seconds for `steps` steps of `w` (on the pool, as `dem` steps), and the sides' forces after.
fn run(w: &World, steps: usize) -> (f64, Vec<Vec3>) {
    let mut w = w.clone();
    let clock = Instant::now();
    on_pool(|| {
        for _ in 0..steps {
            w.step();
        }
    });
    let secs = clock.elapsed().as_secs_f64();
    (secs, w.walls[1..=4].iter().map(|x| x.force).collect())
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let Some(bed) = args.first() else {
        eprintln!("walls: no bed given (usage: walls BED.jsonl [STEPS [GRID]]); skipped");
        return Ok(());
    };
    let number = |k: usize, default: usize| -> Result<usize, String> {
        args.get(k).map_or(Ok(default), |s| {
            s.parse()
                .map_err(|_| format!("walls: '{s}' is not a count"))
        })
    };
    let (steps, grid) = (number(1, 200)?, number(2, 24)?);
    // `cargo bench` runs in shared/: a relative path is also looked for from the workspace.
    let path = std::path::Path::new(bed);
    let from_root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join(bed);
    let path = if path.is_relative() && !path.exists() {
        from_root.as_path()
    } else {
        path
    };
    let file = std::fs::File::open(path).map_err(|e| format!("walls: {bed}: {e}"))?;
    let mut planes = read_world(std::io::BufReader::new(file)).map_err(|e| e.to_string())?;
    planes.renumber_along_space();
    let facets = faceted(&planes, grid)?;
    let n = planes.bodies.len() as f64;
    let (mut best_p, mut best_f) = (f64::INFINITY, f64::INFINITY);
    let mut forces = (Vec::new(), Vec::new());
    for _ in 0..3 {
        let (p, fp) = run(&planes, steps);
        let (f, ff) = run(&facets, steps);
        (best_p, best_f) = (best_p.min(p), best_f.min(f));
        forces = (fp, ff);
    }
    let scale = forces.0.iter().map(|f| f.norm()).fold(0.0, f64::max);
    let differ = (forces.0.iter().zip(&forces.1))
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    println!(
        "walls: {bed}, {steps} steps, {} threads, sides of {} triangles each: planes {:.3e}, \
         facets {:.3e} particle-steps/s (least of 3 rounds; facets cost {:.2}x); side forces \
         differ by {:.1e} of the largest ({scale:.3e} N)",
        rayon::current_num_threads(),
        2 * grid * grid,
        n * steps as f64 / best_p,
        n * steps as f64 / best_f,
        best_f / best_p,
        differ / scale.max(f64::MIN_POSITIVE),
    );
    Ok(())
}
