//! The specimen `pack` makes, as a whole: 36 particles of the nine sharp I_P templates.

use shared::dem::shape::Shape;
use shared::geometry::polygen;
use shared::lab::pack;

/// Local damping takes nothing from a body without contacts, so a rattler would keep the
/// speed and spin the compaction left it and turn freely through a test. The specimen is
/// written still: every body, not only the walls.
#[test]
fn a_packed_specimen_is_at_rest_rattlers_and_all() {
    let templates: Vec<Shape> = (6..=14)
        .map(|faces| {
            let q = polygen::Params {
                faces,
                ..Default::default()
            };
            Shape::from_mesh(&polygen::generate(&q, 7, 0).unwrap().mesh).unwrap()
        })
        .collect();
    let p = pack::Params {
        count: Some(36),
        diameter: 0.07,
        height: 0.14,
        size_min: 0.012,
        size_max: 0.018,
        seed: 3,
        ..pack::Params::default()
    };
    let mut w = pack::cloud(templates, &p).unwrap();
    // Moving on the way: the last report of the equilibrium stage sees bodies in motion.
    let mut moving = 0;
    pack::consolidate(&mut w, &p, 1, |_, w| {
        moving = w.bodies.iter().filter(|b| b.vel.norm() > 0.0).count();
    })
    .unwrap();
    assert!(moving > 0, "no body moved in the last step of the preparation");
    for (i, b) in w.bodies.iter().enumerate() {
        assert_eq!(b.vel.norm(), 0.0, "body {i} moves at {:?}", b.vel);
        assert_eq!(b.ang_mom.norm(), 0.0, "body {i} spins: {:?}", b.ang_mom);
    }
    assert!(w.walls.iter().all(|x| x.velocity.norm() == 0.0));
    assert_eq!(w.energy.kinetic, 0.0);
}
