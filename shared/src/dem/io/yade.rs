//! Reads the peer benchmark's scene format (`peer-scene v1`, `pipelines/yade/README.md`)
//! so that the same scene runs in Yade and here.
//!
//! `box Lx Ly Lz` gives a floor `z = 0` and side walls `x = 0, Lx`, `y = 0, Ly` (open top);
//! each particle line `id k deq x y z nv v1x v1y v1z ...` gives its centroid and its vertices as
//! offsets from it in world axes; the particle is their convex hull. A settled-state file
//! (`id x y z qw qx qy qz`) moves and turns the particles: world vertex = (x, y, z) + R(q) v.
//! The peer's physics parameters: density 2600, friction 0.5 on particles and walls, damping
//! 0.3, gravity 9.81 down; our linear law uses the paper's kn = 1e8 N/m, ks = 5e7 N/m.

use crate::dem::law::Material;
use crate::dem::shape::Shape;
use crate::dem::wall::Wall;
use crate::dem::world::World;
use crate::geometry::hull;
use crate::geometry::mass::equivalent_diameter;
use crate::math::Vec3;
use nalgebra::{Quaternion, UnitQuaternion};
use std::io::BufRead;

fn err(line: usize, msg: impl Into<String>) -> String {
    format!("line {line}: {}", msg.into())
}

/// A world from a peer scene; `settled` optionally moves the particles to a settled state.
/// Each particle gets its own shape (the peer's particles are all different); `World::abrade`
/// turns them into the paper's Ab_k of these I_P shapes.
///
/// With `templates`, particle `i` is not its own polyhedron but template `i mod T` (the nine
/// templates of 6 to 14 faces match the peer's face counts `6 + i mod 9`), scaled to the
/// particle's equivalent-sphere diameter `deq`, its centroid on the particle's and its
/// principal axes along the particle's: the benchmark scene (the nine templates, sizes
/// 10-40 mm) in the peer's box and loose lattice. The bodies then share T shapes.
pub fn read_peer_scene<R: BufRead, S: BufRead>(
    scene: R,
    settled: Option<S>,
    templates: Option<&[Shape]>,
) -> Result<World, String> {
    if templates.is_some_and(|t| t.is_empty()) {
        return Err("no templates".into());
    }
    let material = Material {
        wall_friction: 0.5,
        ..Default::default()
    };
    let mut world = World::new(material, Vec3::new(0.0, 0.0, -9.81));
    let mut boxed = None;
    // Centroid, equivalent-sphere diameter and world vertex offsets of each particle.
    let mut particles: Vec<(Vec3, f64, Vec<Vec3>)> = Vec::new();
    for (k, line) in scene.lines().enumerate() {
        let n = k + 1;
        let line = line.map_err(|e| err(n, e.to_string()))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') || t.starts_with("params") {
            continue;
        }
        let nums: Result<Vec<f64>, _> = t
            .split_whitespace()
            .skip(usize::from(t.starts_with("box")))
            .map(str::parse::<f64>)
            .collect();
        let nums = nums.map_err(|_| err(n, "expected numbers"))?;
        if !nums.iter().all(|x| x.is_finite()) {
            return Err(err(n, "a number is not finite"));
        }
        if t.starts_with("box") {
            if nums.len() != 3 {
                return Err(err(n, "box needs Lx Ly Lz"));
            }
            if !nums.iter().all(|x| *x > 0.0) {
                return Err(err(n, "box needs positive sides Lx Ly Lz"));
            }
            boxed = Some(Vec3::new(nums[0], nums[1], nums[2]));
            continue;
        }
        if nums.len() < 7 {
            return Err(err(
                n,
                "a particle line needs id k deq x y z nv and vertices",
            ));
        }
        let id = nums[0] as usize;
        if id != particles.len() {
            return Err(err(
                n,
                format!(
                    "particle id {id} out of order (expected {})",
                    particles.len()
                ),
            ));
        }
        let nv = nums[6] as usize;
        let holds = (nv.checked_mul(3)).and_then(|k| k.checked_add(7));
        if holds != Some(nums.len()) || nv < 4 {
            return Err(err(
                n,
                format!(
                    "particle {id} says {nv} vertices but the line holds {} numbers after nv",
                    nums.len() - 7
                ),
            ));
        }
        let centre = Vec3::new(nums[3], nums[4], nums[5]);
        let verts = (0..nv)
            .map(|i| Vec3::new(nums[7 + 3 * i], nums[8 + 3 * i], nums[9 + 3 * i]))
            .collect();
        if nums[2] <= 0.0 {
            return Err(err(n, format!("particle {id}: deq must be positive")));
        }
        particles.push((centre, nums[2], verts));
    }
    let size = boxed.ok_or("the scene has no 'box Lx Ly Lz' line")?;
    let walls = [
        (Vec3::zeros(), Vec3::z()),
        (Vec3::zeros(), Vec3::x()),
        (Vec3::new(size.x, 0.0, 0.0), -Vec3::x()),
        (Vec3::zeros(), Vec3::y()),
        (Vec3::new(0.0, size.y, 0.0), -Vec3::y()),
    ];
    world.walls = walls.iter().map(|&(p, n)| Wall::plane(p, n)).collect();
    let mut poses: Vec<(Vec3, UnitQuaternion<f64>)> = particles
        .iter()
        .map(|(c, _, _)| (*c, UnitQuaternion::identity()))
        .collect();
    if let Some(settled) = settled {
        let mut seen = 0;
        for (k, line) in settled.lines().enumerate() {
            let n = k + 1;
            let line = line.map_err(|e| err(n, e.to_string()))?;
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') {
                continue;
            }
            let v: Vec<f64> = t
                .split_whitespace()
                .map(str::parse::<f64>)
                .collect::<Result<_, _>>()
                .map_err(|_| err(n, "settled state: expected numbers"))?;
            if v.len() != 8 || v[0] as usize >= poses.len() {
                return Err(err(
                    n,
                    "settled state: expected 'id x y z qw qx qy qz' for a known id",
                ));
            }
            if !v.iter().all(|x| x.is_finite()) {
                return Err(err(n, "settled state: a number is not finite"));
            }
            let q = Quaternion::new(v[4], v[5], v[6], v[7]);
            // A unit quaternion written to a few digits, not one to be made up from nothing.
            if (q.norm() - 1.0).abs() > 1e-3 {
                return Err(err(
                    n,
                    format!(
                        "settled state: the orientation has norm {}, not 1",
                        q.norm()
                    ),
                ));
            }
            let q = UnitQuaternion::new_normalize(q);
            poses[v[0] as usize] = (Vec3::new(v[1], v[2], v[3]), q);
            seen += 1;
        }
        if seen != poses.len() {
            return Err(format!(
                "settled state gives {seen} particles, the scene has {}",
                poses.len()
            ));
        }
    }
    if let Some(t) = templates {
        for shape in t {
            world.add_shape(shape.clone());
        }
    }
    for (i, ((_, deq, verts), (centre, q))) in particles.iter().zip(&poses).enumerate() {
        let h = hull::convex_hull(verts).map_err(|e| format!("particle {i}: {e}"))?;
        let mut mesh = h.mesh;
        mesh.name = format!("peer{i}");
        let shape = Shape::from_mesh(&mesh).map_err(|e| e.to_string())?;
        // The shape's principal frame sits at centroid_in_mesh, turned by frame_in_mesh, in the
        // particle's offset frame; the pose maps offsets to the world.
        let pos = centre + q * shape.centroid_in_mesh;
        let rot = q * shape.frame_in_mesh;
        match templates {
            Some(t) => {
                let k = i % t.len();
                world.add_body(k as u32, deq / equivalent_diameter(t[k].volume), pos, rot);
            }
            None => {
                let s = world.add_shape(shape);
                world.add_body(s, 1.0, pos, rot);
            }
        }
    }
    Ok(world)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = "# peer-scene v1\nbox 0.1 0.1 0.2\nparams n=1\n0 4 0.01 0.05 0.05 0.05 4 0.01 0 0 0 0.01 0 0 0 0.01 -0.005 -0.005 -0.005\n";

    #[test]
    fn reads_a_scene_and_keeps_world_vertices() {
        let w = read_peer_scene(SCENE.as_bytes(), None::<&[u8]>, None).unwrap();
        assert_eq!((w.bodies.len(), w.walls.len()), (1, 5));
        let b = &w.bodies[0];
        let posed = w.shapes[0].posed(&b.pos, &b.rot, b.scale);
        // Every listed world vertex is a vertex of the posed body.
        for v in [Vec3::new(0.06, 0.05, 0.05), Vec3::new(0.045, 0.045, 0.045)] {
            assert!(
                posed.vertices.iter().any(|p| (p - v).norm() < 1e-12),
                "{v} missing"
            );
        }
    }

    #[test]
    fn a_settled_pose_moves_and_turns() {
        let settled = "0 0.02 0.03 0.04 0 0 0 1\n"; // half a turn about z
        let w = read_peer_scene(SCENE.as_bytes(), Some(settled.as_bytes()), None).unwrap();
        let b = &w.bodies[0];
        let posed = w.shapes[0].posed(&b.pos, &b.rot, b.scale);
        let v = Vec3::new(0.02 - 0.01, 0.03, 0.04); // (0.01, 0, 0) turned half a turn
        assert!(posed.vertices.iter().any(|p| (p - v).norm() < 1e-12));
    }

    #[test]
    fn templates_replace_particles_at_their_size_and_place() {
        let scene = "box 0.2 0.2 0.2\n\
            0 4 0.01 0.05 0.05 0.05 4 0.01 0 0 0 0.01 0 0 0 0.01 -0.005 -0.005 -0.005\n\
            1 4 0.02 0.15 0.05 0.05 4 0.01 0 0 0 0.01 0 0 0 0.01 -0.005 -0.005 -0.005\n\
            2 4 0.03 0.05 0.15 0.05 4 0.01 0 0 0 0.01 0 0 0 0.01 -0.005 -0.005 -0.005\n";
        let cube = Shape::from_mesh(&crate::geometry::mesh::cube(1.0)).unwrap();
        let params = crate::geometry::polygen::Params {
            faces: 8,
            ..Default::default()
        };
        let octa = Shape::from_mesh(
            &crate::geometry::polygen::generate(&params, 7, 0)
                .unwrap()
                .mesh,
        )
        .unwrap();
        let w = read_peer_scene(scene.as_bytes(), None::<&[u8]>, Some(&[cube, octa])).unwrap();
        assert_eq!(
            (w.shapes.len(), w.bodies.len()),
            (2, 3),
            "the bodies share the templates"
        );
        for (i, (b, deq)) in w.bodies.iter().zip([0.01, 0.02, 0.03]).enumerate() {
            assert_eq!(b.shape as usize, i % 2);
            let d =
                equivalent_diameter(w.shapes[b.shape as usize].volume * crate::math::cube(b.scale));
            assert!((d - deq).abs() < 1e-12 * deq, "body {i}: {d} for {deq}");
        }
        // The particle's centroid: the tetrahedron of offsets (0.01, 0, 0), ... has its
        // centroid 0.00125 m from the listed point along each axis.
        let c = Vec3::new(0.05, 0.05, 0.05) + Vec3::repeat(0.00125);
        assert!((w.bodies[0].pos - c).norm() < 1e-12);
        assert!(read_peer_scene(scene.as_bytes(), None::<&[u8]>, Some(&[]))
            .unwrap_err()
            .contains("no templates"));
    }

    #[test]
    fn bad_peer_input() {
        assert!(
            read_peer_scene("0 4 0.01 0 0 0 4 1 2 3\n".as_bytes(), None::<&[u8]>, None)
                .unwrap_err()
                .contains("line 1")
        );
        assert!(read_peer_scene(
            "box 1 1 1\n0 4 0 0 0 0 4 1 0 0 0 1 0 0 0 1 0 0 0\n".as_bytes(),
            None::<&[u8]>,
            None
        )
        .unwrap_err()
        .contains("line 2: particle 0: deq must be positive"));
        assert!(read_peer_scene("box 1 1\n".as_bytes(), None::<&[u8]>, None)
            .unwrap_err()
            .contains("box needs"));
        assert!(
            read_peer_scene("box 0 0 0\n".as_bytes(), None::<&[u8]>, None)
                .unwrap_err()
                .contains("box needs positive sides")
        );
        // A settled state's orientation that is zero, not a number or not of norm 1.
        let scene = "box 0.1 0.1 0.2\n0 4 0.01 0.05 0.05 0.05 4 0.01 0 0 0 0.01 0 0 0 0.01 -0.005 -0.005 -0.005\n";
        for (state, needle) in [
            ("0 0.05 0.05 0.05 0 0 0 0\n", "norm 0"),
            ("0 0.05 0.05 0.05 NaN 0 0 0\n", "not finite"),
            ("0 0.05 0.05 0.05 0.5 0 0 0\n", "norm 0.5"),
        ] {
            let e = read_peer_scene(scene.as_bytes(), Some(state.as_bytes()), None).unwrap_err();
            assert!(e.contains(needle) && e.contains("line 1"), "{e}");
        }
        assert!(
            read_peer_scene("# nothing\n".as_bytes(), None::<&[u8]>, None)
                .unwrap_err()
                .contains("no 'box")
        );
    }
}
