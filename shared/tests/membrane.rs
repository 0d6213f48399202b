//! The membrane alone, no particles: thin-shell theory and its energy audit.

use shared::dem::law::Material;
use shared::dem::membrane::{Guide, Membrane, Pin, Sheet};
use shared::dem::wall::{Wall, WallKind};
use shared::dem::world::World;
use shared::lab::triax::cylinder_membrane;
use shared::math::Vec3;

const RADIUS: f64 = 0.075;
const HEIGHT: f64 = 0.15;
const YOUNG: f64 = 7.8e6;
const POISSON: f64 = 0.5;
const THICKNESS: f64 = 2e-3;

/// A membrane cylinder between two platens (planes at z = 0 and z = HEIGHT), its end rings
/// sliding on them (radially free), `pressure` on its outside (negative: an inner pressure
/// pushing it out), local damping `damping`; no particles.
fn tube(pressure: f64, damping: f64, guided: bool) -> World {
    let material = Material {
        kn: 1.0,
        ks: 0.5,
        damping,
        ..Material::default()
    };
    let mut w = World::new(material, Vec3::zeros());
    w.walls.push(Wall::plane(Vec3::zeros(), Vec3::z()));
    w.walls
        .push(Wall::plane(Vec3::new(0.0, 0.0, HEIGHT), -Vec3::z()));
    let (nodes, triangles, bottom, top) =
        cylinder_membrane(&Vec3::zeros(), &Vec3::z(), RADIUS, 48, 0.0, HEIGHT, 15);
    let pins = (bottom.iter().map(|&node| Pin { node, wall: 0 }))
        .chain(top.iter().map(|&node| Pin { node, wall: 1 }))
        .collect();
    let sheet = Sheet {
        young: YOUNG,
        poisson: POISSON,
        thickness: THICKNESS,
        pressure,
        node_mass: 1e-3,
        kn: 1e6,
        ks: 5e5,
        damping: None,
        reach: 0.01,
    };
    let guide = guided.then_some(Guide { bottom: 0, top: 1 });
    let m = Membrane::new(sheet, nodes.clone(), &triangles, pins, false, guide, 3).unwrap();
    let mut wall = Wall::facets(nodes, triangles);
    wall.membrane = Some(Box::new(m));
    w.walls.push(wall);
    w.dt = 0.2 * w.critical_dt();
    w
}

/// The nodes' mean distance from the axis.
fn mean_radius(w: &World) -> f64 {
    let WallKind::Facets { nodes, .. } = &w.walls[2].kind else {
        panic!("a facet wall")
    };
    nodes.iter().map(|x| x.xy().norm()).sum::<f64>() / nodes.len() as f64
}

/// A membrane cylinder under an inner pressure, its ends free to slide radially on the
/// platens (so no axial strain; free nodes, or nodes guided radially, the axial stress `nu` times the hoop stress), expands as
/// thin-shell theory says: `dr / r = p r (1 - nu^2) / (E t)`, within 1 % (the Green strain's
/// second order is 0.4 % of it here).
#[test]
fn a_membrane_cylinder_under_pressure_expands_as_thin_shell_theory_says() {
    for guided in [false, true] {
        let p = 2e3;
        let mut w = tube(-p, 0.7, guided);
        let r0 = mean_radius(&w);
        for _ in 0..20_000 {
            w.step();
        }
        let expected = p * r0 * (1.0 - POISSON * POISSON) / (YOUNG * THICKNESS);
        let got = mean_radius(&w) / r0 - 1.0;
        eprintln!("guided {guided}: radius change {got:.6e}, thin-shell {expected:.6e}");
        assert!(
            (got / expected - 1.0).abs() < 0.01,
            "radius change {got:.6e} against thin-shell {expected:.6e}"
        );
        // At rest: the nodes stopped, every node at the same radius (a uniform expansion).
        let WallKind::Facets {
            nodes,
            node_velocities,
            ..
        } = &w.walls[2].kind
        else {
            panic!()
        };
        let vmax = node_velocities.iter().map(|v| v.norm()).fold(0.0, f64::max);
        assert!(vmax < 1e-6, "nodes still moving at {vmax:e} m/s");
        let spread = nodes
            .iter()
            .map(|x| x.xy().norm() - r0 * (1.0 + got))
            .fold(0.0f64, |a, d| a.max(d.abs()));
        assert!(spread < 1e-3 * r0 * got, "radius varies by {spread:e} m");
    }
}

/// The membrane's energy audit closes: the pressure's work is its kinetic and elastic energy
/// plus what damping took, undamped (the membrane oscillates) and damped, free and guided;
/// the balance stays within 1 % of the pressure's work at the default step, and its error is
/// the integrator's, first order in the step (kinetic energy counted at the half step): it
/// halves with the step.
#[test]
fn the_membranes_energy_audit_closes() {
    let worst = |damping: f64, guided: bool, refine: f64| {
        let mut w = tube(-2e3, damping, guided);
        w.dt /= refine;
        let mut worst = 0.0f64;
        for _ in 0..(8000.0 * refine) as usize {
            w.step();
            worst = worst.max(w.energy.balance().abs());
        }
        (worst, w.energy)
    };
    for (damping, guided) in [(0.0, false), (0.3, false), (0.0, true), (0.3, true)] {
        let (err, e) = worst(damping, guided, 1.0);
        eprintln!(
            "damping {damping}, guided {guided}: worst balance {err:.3e} J, pressure work {:.3e} J",
            e.pressure_work
        );
        assert!(e.pressure_work > 0.0 && e.membrane_elastic > 0.0, "{e:?}");
        if damping > 0.0 {
            assert!(e.membrane_damping > 0.0, "{e:?}");
        } else {
            assert!(
                e.membrane_kinetic > 0.0 && e.membrane_damping == 0.0,
                "{e:?}"
            );
        }
        assert!(
            err < 1e-2 * e.pressure_work,
            "damping {damping}: balance off by {err:e} J against {:e} J of pressure work",
            e.pressure_work
        );
    }
    let (coarse, _) = worst(0.0, true, 1.0);
    let (fine, _) = worst(0.0, true, 2.0);
    eprintln!("undamped, guided: worst balance {coarse:.3e} J, at half the step {fine:.3e} J");
    assert!(
        (coarse / fine - 2.0).abs() < 0.2,
        "{coarse:e} against {fine:e}"
    );
}

/// A membrane's contact has no shear law (its stiffness is per unit volume): a scene that gives
/// the walls friction beside a membrane is refused with a message that says so, not stepped
/// with a stiffness in N/m^3 taken for a shear spring's N/m.
#[test]
fn wall_friction_beside_a_membrane_is_refused() {
    let mut w = tube(0.0, 0.3, true);
    let mut text = Vec::new();
    shared::dem::io::state::write_world(&w, &mut text).unwrap();
    assert!(shared::dem::io::state::read_world(text.as_slice()).is_ok());
    w.material.wall_friction = 0.3;
    let mut text = Vec::new();
    shared::dem::io::state::write_world(&w, &mut text).unwrap();
    let err = shared::dem::io::state::read_world(text.as_slice())
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("wall_friction must be 0 with a membrane wall, got 0.3"),
        "{err}"
    );
}
