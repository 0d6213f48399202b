//! The container of a specimen: two platens and a cylinder (or a box's four sides), what its
//! walls measure (stresses, the porosity inside them) and where its inside is.

use crate::dem::contacts::Partner;
use crate::dem::wall::{Wall, WallKind};
use crate::dem::world::World;
use crate::geometry::mass::clipped_volume;
use crate::math::{box_excess, cube, Vec3};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::PI;

/// The bottom platen's index among the walls (a plane, normal +z).
pub const BOTTOM: usize = 0;

/// The top platen's index (a plane, normal -z).
pub const TOP: usize = 1;

/// The cylinder wall's index; in a box, the first of the four side planes (normals +x, -x,
/// +y, -y).
pub const SIDE: usize = 2;

/// A container's cross-section.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Section {
    /// The prism of `segments` facets inscribed in the circle of `radius` about the z axis.
    Circle { radius: f64, segments: u32 },
    /// From `x[0]` to `x[1]` and `y[0]` to `y[1]`.
    Rect { x: [f64; 2], y: [f64; 2] },
}

/// A container's inside: its cross-section, from z = `bottom` to `top`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub section: Section,
    pub bottom: f64,
    pub top: f64,
}

/// What the servo needs of one wall: its area, its distance from the container's middle, and
/// its share of the mean stress.
pub struct WallGeometry {
    pub area: f64,
    pub half: f64,
    pub weight: f64,
}

impl Bounds {
    pub fn height(&self) -> f64 {
        self.top - self.bottom
    }

    /// The cross-section's area (the cylinder's: its facet polygon's).
    pub fn area(&self) -> f64 {
        match self.section {
            Section::Circle { radius, segments } => {
                let n = f64::from(segments);
                0.5 * n * radius * radius * (2.0 * PI / n).sin()
            }
            Section::Rect { x, y } => (x[1] - x[0]) * (y[1] - y[0]),
        }
    }

    /// The cross-section's perimeter (the cylinder's: its facet polygon's).
    pub fn perimeter(&self) -> f64 {
        match self.section {
            Section::Circle { radius, segments } => {
                let n = f64::from(segments);
                2.0 * n * radius * (PI / n).sin()
            }
            Section::Rect { x, y } => 2.0 * ((x[1] - x[0]) + (y[1] - y[0])),
        }
    }

    /// Whether `x` is inside, at least `margin` from every wall (a negative margin lets it
    /// out by as much). The cylinder's wall is its circle, not its facets.
    pub fn holds(&self, x: &Vec3, margin: f64) -> bool {
        let across = match self.section {
            Section::Circle { radius, .. } => x.xy().norm() < radius - margin,
            Section::Rect { x: xs, y: ys } => {
                x.x > xs[0] + margin
                    && x.x < xs[1] - margin
                    && x.y > ys[0] + margin
                    && x.y < ys[1] - margin
            }
        };
        across && x.z > self.bottom + margin && x.z < self.top - margin
    }

    /// A uniformly random point of the cross-section's bounding rectangle, at a uniformly random
    /// height.
    pub fn draw(&self, rng: &mut ChaCha8Rng) -> Vec3 {
        let (x, y) = match self.section {
            Section::Circle { radius, .. } => ([-radius, radius], [-radius, radius]),
            Section::Rect { x, y } => (x, y),
        };
        Vec3::new(
            rng.random_range(x[0]..=x[1]),
            rng.random_range(y[0]..=y[1]),
            rng.random_range(self.bottom..=self.top),
        )
    }

    /// The same container scaled by `f` about the bottom's middle.
    pub fn scaled(&self, f: f64) -> Bounds {
        let section = match self.section {
            Section::Circle { radius, segments } => Section::Circle {
                radius: radius * f,
                segments,
            },
            Section::Rect { x, y } => Section::Rect {
                x: x.map(|v| v * f),
                y: y.map(|v| v * f),
            },
        };
        Bounds {
            section,
            bottom: self.bottom * f,
            top: self.top * f,
        }
    }

    /// The walls that make this container, in the order of [`Container`].
    pub fn walls(&self) -> Vec<Wall> {
        let mut walls = vec![
            Wall::plane(Vec3::new(0.0, 0.0, self.bottom), Vec3::z()),
            Wall::plane(Vec3::new(0.0, 0.0, self.top), -Vec3::z()),
        ];
        match self.section {
            Section::Circle { radius, segments } => {
                // Twice the height: the platens stay inside it as they move.
                let h = self.height();
                walls.push(Wall::cylinder(
                    Vec3::new(0.0, 0.0, self.bottom - 0.5 * h),
                    Vec3::z(),
                    radius,
                    2.0 * h,
                    segments,
                ));
            }
            Section::Rect { x, y } => {
                walls.push(Wall::plane(Vec3::new(x[0], 0.0, 0.0), Vec3::x()));
                walls.push(Wall::plane(Vec3::new(x[1], 0.0, 0.0), -Vec3::x()));
                walls.push(Wall::plane(Vec3::new(0.0, y[0], 0.0), Vec3::y()));
                walls.push(Wall::plane(Vec3::new(0.0, y[1], 0.0), -Vec3::y()));
            }
        }
        walls
    }

    /// Each wall's area, distance from the middle and share of the mean stress (its
    /// directions over 3, a platen's halved as it shares its direction with the other).
    pub fn geometry(&self) -> Vec<WallGeometry> {
        let h = self.height();
        let platen = || WallGeometry {
            area: self.area(),
            half: 0.5 * h,
            weight: 1.0 / 6.0,
        };
        let mut out = vec![platen(), platen()];
        match self.section {
            Section::Circle { radius, .. } => out.push(WallGeometry {
                area: self.perimeter() * h,
                half: radius,
                weight: 2.0 / 3.0,
            }),
            Section::Rect { x, y } => {
                for (side, across) in [(y[1] - y[0], x[1] - x[0]), (x[1] - x[0], y[1] - y[0])] {
                    for _ in 0..2 {
                        out.push(WallGeometry {
                            area: side * h,
                            half: 0.5 * across,
                            weight: 1.0 / 6.0,
                        });
                    }
                }
            }
        }
        out
    }

    /// "0.3000 m across and 0.6000 m high", or "0.3000 x 0.3000 m and ...".
    pub fn describe(&self) -> String {
        let across = match self.section {
            Section::Circle { radius, .. } => format!("{:.4} m across", 2.0 * radius),
            Section::Rect { x, y } => format!("{:.4} x {:.4} m", x[1] - x[0], y[1] - y[0]),
        };
        format!("{across} and {:.4} m high", self.height())
    }
}

/// The container of a specimen made by [`cloud`], as its walls are now; `None` when the walls
/// are not a pack container (bottom and top platens, then a cylinder or four side planes).
pub fn container(w: &World) -> Option<Bounds> {
    let plane = |k: usize, normal: Vec3| match w.walls.get(k).map(|x| &x.kind) {
        Some(WallKind::Plane { normal: n, offset }) if *n == normal => Some(*offset),
        _ => None,
    };
    let (bottom, top) = (plane(BOTTOM, Vec3::z())?, -plane(TOP, -Vec3::z())?);
    let section = match (w.walls.len(), w.walls.get(SIDE).map(|x| &x.kind)) {
        (
            3,
            Some(WallKind::Cylinder {
                radius, segments, ..
            }),
        ) => Section::Circle {
            radius: *radius,
            segments: *segments,
        },
        (6, _) => Section::Rect {
            x: [plane(SIDE, Vec3::x())?, -plane(SIDE + 1, -Vec3::x())?],
            y: [plane(SIDE + 2, Vec3::y())?, -plane(SIDE + 3, -Vec3::y())?],
        },
        _ => return None,
    };
    Some(Bounds {
        section,
        bottom,
        top,
    })
}

/// [`container`] of a world made by [`cloud`].
pub fn bounds(w: &World) -> Bounds {
    container(w).expect("the walls of a pack container")
}

/// Wall stresses (compression positive, Pa) and each wall's contact count, in the walls'
/// order: a plane's the normal force over its area, the cylinder's the radial force of its
/// contacts over its facets' area between the platens. `w` is made by [`cloud`].
pub fn wall_stresses(w: &World) -> (Vec<f64>, Vec<usize>) {
    let b = bounds(w);
    stresses_in(w, &b, &b.geometry())
}

/// [`wall_stresses`] in the container `b` of these walls' `geometry`.
pub fn stresses_in(w: &World, b: &Bounds, geometry: &[WallGeometry]) -> (Vec<f64>, Vec<usize>) {
    let mut counts = vec![0usize; geometry.len()];
    let mut radial = 0.0;
    let first = w.contacts.lower_bound(&(Partner::Wall(0), 0));
    for (&(partner, _), c) in w.contacts.iter().skip(first) {
        let Partner::Wall(k) = partner else { continue };
        let k = k as usize;
        if let Some(n) = counts.get_mut(k) {
            *n += 1;
        }
        if matches!(b.section, Section::Circle { .. }) && k == SIDE {
            let out = Vec3::new(c.point.x, c.point.y, 0.0);
            let len = out.norm();
            if len > 0.0 {
                let push = -(c.normal * c.normal_force + c.shear);
                radial += push.dot(&out) / len;
            }
        }
    }
    let stresses = (w.walls.iter().zip(geometry))
        .map(|(wall, g)| match &wall.kind {
            WallKind::Plane { normal, .. } => -wall.force.dot(normal) / g.area,
            _ => radial / g.area,
        })
        .collect();
    (stresses, counts)
}

/// Solid volume of the bodies, m^3.
pub fn solid_volume(w: &World) -> f64 {
    w.bodies
        .iter()
        .map(|b| w.shapes[b.shape as usize].volume * cube(b.scale))
        .sum()
}

/// Porosity of the specimen (made by [`cloud`]) in its container.
pub fn porosity(w: &World) -> f64 {
    porosity_of(&bounds(w), solid_volume(w))
}

/// The container's core: the prism left when every wall moves `layer` inwards, as the
/// half-spaces `n . x <= d` that bound it and its volume; `None` when nothing is left. A
/// cylinder's core is a polygon of as many sides as its facets (in any orientation: the sides
/// only bound a region), its apothem `layer` shorter.
pub fn core(b: &Bounds, layer: f64) -> Option<(Vec<(Vec3, f64)>, f64)> {
    let (bottom, top) = (b.bottom + layer, b.top - layer);
    let mut planes = vec![(-Vec3::z(), -bottom), (Vec3::z(), top)];
    let section = match b.section {
        Section::Circle { radius, segments } => {
            let n = f64::from(segments);
            let apothem = radius * (PI / n).cos() - layer;
            planes.extend((0..segments).map(|k| {
                let a = 2.0 * PI * f64::from(k) / n;
                (Vec3::new(a.cos(), a.sin(), 0.0), apothem)
            }));
            (apothem > 0.0).then(|| Section::Circle {
                radius: apothem / (PI / n).cos(),
                segments,
            })
        }
        Section::Rect { x, y } => {
            let (x, y) = ([x[0] + layer, x[1] - layer], [y[0] + layer, y[1] - layer]);
            planes.extend([
                (-Vec3::x(), -x[0]),
                (Vec3::x(), x[1]),
                (-Vec3::y(), -y[0]),
                (Vec3::y(), y[1]),
            ]);
            (x[0] < x[1] && y[0] < y[1]).then_some(Section::Rect { x, y })
        }
    }?;
    let inset = Bounds {
        section,
        bottom,
        top,
    };
    (bottom < top).then(|| (planes, inset.area() * inset.height()))
}

/// Porosity of the container's core, `layer` in from every wall ([`core`]): the bodies' volume
/// inside it (each straddling body clipped exactly, [`clipped_volume`]) over its volume.
/// It leaves out the layer along the walls, where particles pack looser against a flat surface
/// (docs/models/pack.md has what it measures, small sample against specimen). `None` when the layer
/// leaves no core. `w` is made by [`cloud`].
pub fn core_porosity(w: &World, layer: f64) -> Option<f64> {
    let (planes, volume) = core(&bounds(w), layer)?;
    let solid: f64 = w
        .bodies
        .iter()
        .map(|body| {
            let s = &w.shapes[body.shape as usize];
            let posed = s.posed(&body.pos, &body.rot, body.scale);
            let (lo, hi) = (posed.lo, posed.hi);
            // Wholly beyond one plane (its box is), or wholly inside all of them.
            if (planes.iter()).any(|(n, d)| box_excess(&-n, -d, &lo, &hi) <= 0.0) {
                return 0.0;
            }
            if (planes.iter()).all(|(n, d)| box_excess(n, *d, &lo, &hi) <= 0.0) {
                return s.volume * cube(body.scale);
            }
            let faces: Vec<Vec<Vec3>> = (0..s.face_count())
                .map(|f| {
                    (s.face(f).iter())
                        .map(|&i| posed.vertex(s, i as usize))
                        .collect()
                })
                .collect();
            clipped_volume(&faces, &planes)
        })
        .sum();
    Some(1.0 - solid / volume)
}

/// [`porosity`] for bodies of `solid` volume in all.
pub fn porosity_of(b: &Bounds, solid: f64) -> f64 {
    1.0 - solid / (b.area() * b.height())
}

/// The mean of the wall stresses: `(sigma_x + sigma_y + sigma_z) / 3`, each direction's
/// stress the mean of its walls'.
pub fn mean_stress(geometry: &[WallGeometry], stresses: &[f64]) -> f64 {
    geometry
        .iter()
        .zip(stresses)
        .map(|(g, s)| g.weight * s)
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::dem::shape::Shape;
    use crate::lab::pack::{cloud, Container, Params};
    use nalgebra::UnitQuaternion;

    #[test]
    fn core_porosity_counts_the_part_of_a_straddling_body_inside_the_core() {
        // One cube in a box 200 x 160 x 120 mm, its centre on the core's x-min side 30 mm in:
        // half of it is inside, upright or turned about z (a cube is symmetric about its
        // centre), and none of it when it lies wholly in the layer.
        let cube = Shape::from_mesh(&crate::geometry::mesh::cube(0.5)).unwrap();
        let p = Params {
            container: Container::Box,
            count: Some(1),
            width: 0.2,
            depth: 0.16,
            height: 0.12,
            size_min: 0.02,
            size_max: 0.02,
            ..Params::default()
        };
        let mut w = cloud(vec![cube], &p).unwrap();
        let b = bounds(&w);
        let Section::Rect { x, y } = b.section else {
            panic!("a box")
        };
        let layer = 0.03;
        let core =
            (x[1] - x[0] - 2.0 * layer) * (y[1] - y[0] - 2.0 * layer) * (b.height() - 2.0 * layer);
        let side = w.bodies[0].scale;
        let middle = Vec3::new(x[0] + layer, 0.5 * (y[0] + y[1]), 0.5 * (b.bottom + b.top));
        for turn in [0.0, 0.3, PI / 4.0] {
            w.bodies[0].pos = middle;
            w.bodies[0].rot = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), turn);
            let expected = 1.0 - 0.5 * crate::math::cube(side) / core;
            let got = core_porosity(&w, layer).unwrap();
            assert!(
                (got - expected).abs() < 1e-12,
                "turn {turn}: {got} {expected}"
            );
        }
        w.bodies[0].pos.x = x[0] + 0.4 * layer;
        assert_eq!(core_porosity(&w, layer), Some(1.0));
        // No layer and the cube inside: the container's porosity.
        w.bodies[0].pos = middle + Vec3::x() * 0.05;
        let whole = core_porosity(&w, 0.0).unwrap();
        assert!(
            (whole - porosity(&w)).abs() < 1e-12,
            "{whole} {}",
            porosity(&w)
        );
        // A layer that leaves nothing.
        assert_eq!(core_porosity(&w, 0.061), None);
        // A cylinder's core without a layer is its facet polygon, as the porosity's.
        let q = Params {
            container: Container::Cylinder,
            diameter: 0.1,
            ..p.clone()
        };
        let c = cloud(w.shapes.clone(), &q).unwrap();
        let whole = core_porosity(&c, 0.0).unwrap();
        assert!(
            (whole - porosity(&c)).abs() < 1e-12,
            "{whole} {}",
            porosity(&c)
        );
    }
}
