//! The box scene: 200 mixed polyhedra (the nine I_P templates of 6 to 14 faces and
//! their Ab_3 hulls) falling into a box. Without damping or friction the total energy is kept;
//! with them the energy audit closes. Run in release mode (`make test`).
//!
//! The contacts are softer than the paper's (kn = 1e5 N/m instead of 1e8): conservation does
//! not depend on the stiffness, and a 30x larger time step keeps the test to minutes.

use shared::dem::law::Material;
use shared::dem::scenes::{conservative, dissipative, run, soft, Run, BODIES, T};
use shared::dem::world::World;

/// The box scene at the default time step, 0.2 x critical.
fn box_scene(material: Material) -> World {
    let w = shared::dem::scenes::box_scene(material, 0.2);
    assert!(w.shapes[1].vertices.len() > 300, "Ab_3 hulls are large");
    w
}

/// KNOWN FAILURE (the box scene, conservative half). Undamped and frictionless the
/// 200 bodies bounce as an elastic gas (at most 27 contacts at once); the energy drifts by up to
/// 0.41 J against a peak kinetic energy of 6.95 J (5.9 %, target 1 %). Cause, measured on
/// single impacts of random pairs (2 m/s, random poses, no spin): the paper's law F = kn V/|S_B|
/// at the overlap centroid is not conservative once the overlap is not a flat slab (the force
/// centre and the depth do not come from one potential), and an oblique impact ends with up to
/// +-2.4 % of its energy changed (mean ~0), the same for time steps of 0.2 and 0.05 x critical
/// and still 2.4 % at kn = 1e8 N/m, so the drift is the law's, not the integrator's. The drift
/// falls with stiffness as fewer contacts overlap in time: 3.1 % at kn = 1e6, 1.1 % at 1e7
/// (these two measured before contacts carried their work; at 1e5 that changed 5.7 % to 5.9 %),
/// and at the paper's kn = 1e8 the test passes (0.56 %, the test below). See docs/models/contact.md.
#[test]
#[ignore = "known failure: 5.9 % energy drift in undamped impacts, see the doc comment"]
fn two_hundred_mixed_polyhedra_in_a_box_keep_their_energy() {
    keep_their_energy(soft());
}

/// The box scene's conservative half with the stiffness of `material`: undamped and frictionless, the
/// energy stays within 1 % of the peak kinetic energy.
fn keep_their_energy(material: Material) {
    let w = box_scene(conservative(material));
    let r = run(w, T);
    eprintln!(
        "conservative, kn = {:e}: drift {:.3e} J, peak kinetic {:.3e} J, gravity work {:.3e} J, {} contacts at most, {} collisions",
        material.kn, r.drift, r.peak_kinetic, r.gravity_work, r.contacts, r.collisions
    );
    // Not vacuous: every body hits the floor or another body, on average once at least.
    assert!(
        r.collisions >= BODIES,
        "the bodies must collide: {} collisions",
        r.collisions
    );
    assert!(
        r.drift < 0.01 * r.peak_kinetic,
        "energy drift {:e} J vs peak kinetic {:e} J",
        r.drift,
        r.peak_kinetic
    );
}

/// The box scene's conservative half at the paper's stiffness, kn = 1e8 N/m (ks = kn / 2): the drift
/// falls with stiffness (above), and this is the stiffness the engine is for. About 30x the
/// steps of the soft run (dt ~ 1/sqrt(kn)).
/// Measured (2026-12-03, 2 threads): drift 0.043 J against a peak kinetic energy of 6.77 J
/// (**0.63 %**), 2959 collisions (at most 4 contacts at once: at this stiffness an impact lasts
/// microseconds), in 42 s: part of `make test`.
#[test]
fn two_hundred_mixed_polyhedra_in_a_box_keep_their_energy_at_the_papers_stiffness() {
    let paper = Material::default();
    assert_eq!((paper.kn, paper.ks), (1e8, 5e7), "the paper's stiffness");
    keep_their_energy(paper);
}

/// The box scene's dissipative half: with friction and local damping, what they
/// dissipate plus kinetic and elastic energy must equal the work of gravity within 1 %.
/// Measured: 0.068 J against 8.09 J of gravity work (0.84 %), 142 contacts at most, 35 s in
/// release mode on 2 cores. It closed only to 1.35 % while the elastic energy was taken as
/// Fn^2 / 2kn, which is a third of the work stored by a vertex pressed into a face (the depth
/// V / |S_B| is a third of the penetration): contacts now carry the work done on them.
#[test]
fn two_hundred_mixed_polyhedra_in_a_box_close_the_energy_audit() {
    let w = box_scene(dissipative(soft()));
    let Run {
        drift,
        gravity_work: gravity,
        contacts,
        ..
    } = run(w, T);
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
