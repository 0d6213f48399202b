//! Time step against energy error, the "speed against error" table for the time step:
//! the box scene (200 I_P and Ab_3 bodies rained into a box, soft kn = 1e5 N/m, 0.45 s) at
//! three safety factors, once with friction and damping (how well the energy audit closes)
//! and once undamped and frictionless (how far the total energy drifts). Prints a Markdown
//! table with the wall time and throughput of each run (all threads). Run by `make bench`:
//! `cargo bench -p granular-shared --bench timestep`.

use shared::dem::scenes::{box_scene, conservative, dissipative, run, soft, BODIES, T};
use std::time::Instant;

fn main() {
    let soft = soft();
    let (dissipative, conservative) = (dissipative(soft), conservative(soft));
    println!(
        "The box scene, {BODIES} bodies, {T} s simulated, kn = {:e} N/m",
        soft.kn
    );
    println!();
    println!("| dt / critical | audit error, friction and damping | energy drift, undamped and frictionless | steps | wall time (both runs) | particle-steps/s |");
    println!("|---|---|---|---|---|---|");
    for safety in [0.1, 0.2, 0.4] {
        let clock = Instant::now();
        let d = run(box_scene(dissipative, safety), T);
        let c = run(box_scene(conservative, safety), T);
        let secs = clock.elapsed().as_secs_f64();
        let steps = d.steps + c.steps;
        println!(
            "| {safety} | {:.2} % | {:.2} % | {} + {} | {secs:.1} s | {:.2e} |",
            100.0 * d.drift / d.gravity_work,
            100.0 * c.drift / c.peak_kinetic,
            d.steps,
            c.steps,
            (steps as f64 * BODIES as f64) / secs
        );
    }
}
