//! Scenes the tests and benchmarks share: the box of 200 mixed
//! polyhedra (the nine I_P templates of 6 to 14 faces and their Ab_3 hulls, `polygen --faces
//! 6..14 --seed 7`), rained into a box, and a run that follows its energy audit.

use crate::dem::law::Material;
use crate::dem::shape::Shape;
use crate::dem::wall::Wall;
use crate::dem::world::World;
use crate::geometry::mass::equivalent_diameter;
use crate::geometry::polygen::{generate, Params};
use crate::geometry::subdiv::subdivide;
use crate::math::Vec3;
use nalgebra::UnitQuaternion;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Bodies in the box scene.
pub const BODIES: usize = 200;
/// Simulated time of the box scene: the grid falls and piles up.
pub const T: f64 = 0.45;

/// The box scene's soft contacts (kn = 1e5 N/m, ks = kn / 2; the paper's otherwise): conservation does
/// not depend on the stiffness, and a 30x larger time step than at 1e8 keeps the run to seconds.
pub fn soft() -> Material {
    Material {
        kn: 1e5,
        ks: 5e4,
        ..Material::default()
    }
}

/// The box scene's dissipative half: `material` with wall friction 0.5 too (friction and damping as
/// given).
pub fn dissipative(material: Material) -> Material {
    Material {
        wall_friction: 0.5,
        ..material
    }
}

/// The box scene's conservative half: `material` without friction or damping.
pub fn conservative(material: Material) -> Material {
    Material {
        friction: 0.0,
        wall_friction: 0.0,
        damping: 0.0,
        ..material
    }
}

/// The box scene: templates, bodies rained in with random poses and small velocities, a floor
/// and four side walls 0.44 m apart; time step `safety` x critical.
pub fn box_scene(material: Material, safety: f64) -> World {
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
    let mut rng = ChaCha8Rng::seed_from_u64(6);
    // Sizes (equivalent-sphere diameters) uniform in 20..30 mm.
    let picks: Vec<(u32, f64)> = (0..BODIES)
        .map(|i| {
            let shape = ((i % 9) * 2 + (i / 9) % 2) as u32;
            let s = &w.shapes[shape as usize];
            (
                shape,
                rng.random_range(0.020..0.030) / equivalent_diameter(s.volume),
            )
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
                let dh2 = crate::math::square(p.x - x) + crate::math::square(p.y - y);
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
    w.dt = safety * w.critical_dt();
    w
}

/// What a run of a scene measured.
#[derive(Clone, Copy, Debug)]
pub struct Run {
    /// Largest drift of the audit's balance from its value after the first step, J.
    pub drift: f64,
    pub peak_kinetic: f64,
    pub gravity_work: f64,
    /// Most contacts at once.
    pub contacts: usize,
    /// Contacts that began during the run (collisions, with walls or bodies).
    pub collisions: usize,
    /// Steps taken.
    pub steps: u64,
}

/// Runs `w` for `t` seconds, following the audit's balance ([`crate::dem::energy::Energy::balance`]).
pub fn run(mut w: World, t: f64) -> Run {
    w.step();
    let start = w.energy.balance();
    let (mut drift, mut peak_kinetic): (f64, f64) = (0.0, 0.0);
    let (mut contacts, mut collisions) = (0, 0);
    while w.time < t {
        let before: Vec<_> = w.contacts.keys().copied().collect();
        w.step();
        collisions += w
            .contacts
            .keys()
            .filter(|k| before.binary_search(k).is_err())
            .count();
        drift = drift.max((w.energy.balance() - start).abs());
        peak_kinetic = peak_kinetic.max(w.energy.kinetic);
        contacts = contacts.max(w.contacts.len());
    }
    Run {
        drift,
        peak_kinetic,
        gravity_work: w.energy.gravity_work,
        contacts,
        collisions,
        steps: w.step,
    }
}
