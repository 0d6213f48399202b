//! The fabric tensors on contact sets with known answers (the paper's Eqs. 11-19).

use nalgebra::UnitQuaternion;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared::math::{random_rotation, Mat3, Vec3};
use shared::micro::fabric::{deviator, scalar, Fabric, Sample};
use shared::micro::stress::invariants;

/// 840 unit vectors that average every polynomial of degree 9 or less over the sphere
/// exactly: the icosahedron's 12 vertices 25 times each and the dual dodecahedron's 20
/// vertices 27 times each (the 32-point icosahedral rule, its weights 25/840 and 27/840).
fn design() -> Vec<Vec3> {
    let g = (1.0 + 5f64.sqrt()) / 2.0;
    let signs = [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)];
    let mut points = Vec::new();
    for &(a, b) in &signs {
        for v in [
            Vec3::new(0.0, a, b * g),
            Vec3::new(a, b * g, 0.0),
            Vec3::new(b * g, 0.0, a),
        ] {
            points.extend(std::iter::repeat_n(v.normalize(), 25));
        }
    }
    let mut dodeca = Vec::new();
    for x in [-1.0, 1.0] {
        for y in [-1.0, 1.0] {
            for z in [-1.0, 1.0] {
                dodeca.push(Vec3::new(x, y, z));
            }
        }
    }
    for &(a, b) in &signs {
        dodeca.extend([
            Vec3::new(0.0, a * g, b / g),
            Vec3::new(a * g, b / g, 0.0),
            Vec3::new(b / g, 0.0, a * g),
        ]);
    }
    for v in dodeca {
        points.extend(std::iter::repeat_n(v.normalize(), 27));
    }
    points
}

#[test]
fn the_design_averages_sixth_degree_polynomials_exactly() {
    // The premise of the exact tests below: <x^6> = 1/7, <x^4 y^2> = 1/35, <x^2 y^2 z^2> = 1/105.
    let p = design();
    let mean = |f: &dyn Fn(&Vec3) -> f64| p.iter().map(f).sum::<f64>() / p.len() as f64;
    assert!((mean(&|v| v.x.powi(6)) - 1.0 / 7.0).abs() < 1e-14);
    assert!((mean(&|v| v.x.powi(4) * v.y.powi(2)) - 1.0 / 35.0).abs() < 1e-14);
    assert!((mean(&|v| v.y.powi(4) * v.x.powi(2)) - 1.0 / 35.0).abs() < 1e-14);
    assert!((mean(&|v| (v.x * v.y * v.z).powi(2)) - 1.0 / 105.0).abs() < 1e-14);
    assert!(mean(&|v| v.x.powi(5) * v.y).abs() < 1e-14);
}

/// A contact along `n` with the normal branch length `bn`, normal force `fnorm` and no
/// tangential parts.
fn normal_contact(n: Vec3, bn: f64, fnorm: f64) -> Sample {
    Sample {
        normal: n,
        branch: n * bn,
        force: n * fnorm,
    }
}

/// A deviatoric tensor with off-diagonal terms.
fn deviatoric(scale: f64) -> Mat3 {
    deviator(&Mat3::new(
        0.5, 0.1, -0.05, 0.1, -0.2, 0.08, -0.05, 0.08, 0.3,
    )) * scale
}

/// Along z, compression positive: the loading direction of a triaxial test.
fn axial() -> Mat3 {
    Mat3::from_diagonal(&Vec3::new(-1.0, -1.0, 2.0))
}

fn quad(a: &Mat3, n: &Vec3) -> f64 {
    (n.transpose() * a * n)[(0, 0)]
}

fn max_abs(m: &Mat3) -> f64 {
    m.iter().fold(0.0f64, |a, x| a.max(x.abs()))
}

#[test]
fn isotropic_normals_give_a_third_of_the_identity_and_no_anisotropy() {
    let turn = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
    let set: Vec<Sample> = design()
        .into_iter()
        .map(|n| normal_contact(turn * n, 0.02, 7.0))
        .collect();
    let f = Fabric::of(&set).unwrap();
    assert!(
        max_abs(&(f.phi_c - Mat3::identity() / 3.0)) < 1e-14,
        "{}",
        f.phi_c
    );
    for (k, a) in f.scalars(&axial()).iter().enumerate() {
        assert!(a.abs() < 1e-13, "anisotropy {k}: {a}");
    }
    assert!((f.b0 / 0.02 - 1.0).abs() < 1e-14 && (f.f0 / 7.0 - 1.0).abs() < 1e-14);
}

/// `n` unit normals drawn from the density `(1 + A : n n) / 4 pi` by rejection.
fn drawn(a: &Mat3, n: usize, rng: &mut ChaCha8Rng) -> Vec<Vec3> {
    let top = 1.0 + 1.5 * max_abs(a) * 3.0;
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let v = random_rotation(rng) * Vec3::z();
        if rng.random::<f64>() * top < 1.0 + quad(a, &v) {
            out.push(v);
        }
    }
    out
}

#[test]
fn normals_drawn_from_a_second_order_density_give_back_its_tensor() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let a = deviatoric(1.0);
    let normals = drawn(&a, 200_000, &mut rng);
    // Forces that follow f0 (1 + B : n n) over that anisotropic density: the weights
    // 1 / (1 + A^c : n n) take the density out, and A^fn comes back as B.
    let b = deviatoric(-0.6);
    let set: Vec<Sample> = normals
        .iter()
        .map(|&n| normal_contact(n, 0.01, 3.0 * (1.0 + quad(&b, &n))))
        .collect();
    let f = Fabric::of(&set).unwrap();
    // Sampling error of a mean of 2e5: about 7.5 * 0.3 / 450 = 0.005.
    assert!(max_abs(&(f.a[0] - a)) < 0.02, "A^c {} against {a}", f.a[0]);
    assert!(max_abs(&(f.a[3] - b)) < 0.03, "A^fn {} against {b}", f.a[3]);
    assert!(max_abs(&f.a[1]) < 0.02, "A^bn {}", f.a[1]);
}

#[test]
fn normal_forces_and_branches_that_follow_a_quadratic_give_back_its_tensor() {
    let (b, fa) = (deviatoric(0.4), deviatoric(-0.7));
    let set: Vec<Sample> = design()
        .into_iter()
        .map(|n| normal_contact(n, 0.01 * (1.0 + quad(&b, &n)), 5.0 * (1.0 + quad(&fa, &n))))
        .collect();
    let f = Fabric::of(&set).unwrap();
    assert!(max_abs(&(f.a[1] - b)) < 1e-13, "{}", f.a[1]);
    assert!(max_abs(&(f.a[3] - fa)) < 1e-13, "{}", f.a[3]);
    assert!((f.b0 - 0.01).abs() < 1e-15 && (f.f0 - 5.0).abs() < 1e-13);
}

#[test]
fn tangential_forces_and_branches_give_their_anisotropies() {
    // f^t t = f0 (C n - (n.C n) n), the shear part of a deviatoric traction: Omega^ft's
    // deviator is 2 f0 / 15 (C - ...) and A^ft = 15/3 of it over f0.
    let c = deviatoric(0.5);
    let set: Vec<Sample> = design()
        .into_iter()
        .map(|n| {
            let shear = c * n - n * quad(&c, &n);
            Sample {
                normal: n,
                branch: n * 0.01 + shear * 0.01,
                force: n * 4.0 + shear * 4.0,
            }
        })
        .collect();
    let f = Fabric::of(&set).unwrap();
    // <(C n - (n.C.n) n) n^T> = C/3 - 2 C/15 = C/5 for deviatoric C; A^ft = 5 (C/5) = C.
    assert!(max_abs(&(f.a[4] - c)) < 1e-13, "{}", f.a[4]);
    assert!(max_abs(&(f.a[2] - c)) < 1e-13, "{}", f.a[2]);
}

#[test]
fn rotating_the_set_rotates_the_tensors_and_keeps_the_scalars() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let normals = drawn(&deviatoric(1.2), 5000, &mut rng);
    let set: Vec<Sample> = normals
        .iter()
        .map(|&n| Sample {
            normal: n,
            branch: n * 0.01 + Vec3::new(rng.random(), rng.random(), rng.random()) * 1e-3,
            force: n * (1.0 + rng.random::<f64>()) + Vec3::new(rng.random(), 0.0, 0.1),
        })
        .collect();
    let turn = random_rotation(&mut rng);
    let r = turn.to_rotation_matrix().into_inner();
    let turned: Vec<Sample> = set
        .iter()
        .map(|s| Sample {
            normal: turn * s.normal,
            branch: turn * s.branch,
            force: turn * s.force,
        })
        .collect();
    let (f, g) = (Fabric::of(&set).unwrap(), Fabric::of(&turned).unwrap());
    let s = axial();
    for k in 0..5 {
        assert!(
            max_abs(&(r * f.a[k] * r.transpose() - g.a[k])) < 1e-12,
            "tensor {k}"
        );
    }
    let (a, b) = (f.scalars(&s), g.scalars(&(r * s * r.transpose())));
    for k in 0..5 {
        assert!((a[k] - b[k]).abs() < 1e-12, "scalar {k}: {} {}", a[k], b[k]);
    }
}

#[test]
fn the_scalar_anisotropy_changes_sign_with_the_loading_direction() {
    // Normals gathered about z: stronger along z. Compression along z: positive; extension
    // along z (the major stress in the plane): negative, the same size.
    let a = Mat3::from_diagonal(&Vec3::new(-0.2, -0.2, 0.4));
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let set: Vec<Sample> = drawn(&a, 20_000, &mut rng)
        .into_iter()
        .map(|n| normal_contact(n, 0.01, 1.0))
        .collect();
    let f = Fabric::of(&set).unwrap();
    let (up, down) = (f.scalars(&axial())[0], f.scalars(&-axial())[0]);
    // sqrt(3/2 A:A) = 0.6, less the sampling error.
    assert!(up > 0.55 && up < 0.65, "{up}");
    assert_eq!(up, -down);
    assert_eq!(scalar(&a, &axial()), -scalar(&a, &-axial()));
}

/// The paper's Eq. 8 over the pairs: `(1/V) sum f l^T`.
fn contact_stress(set: &[Sample], volume: f64) -> Mat3 {
    set.iter()
        .fold(Mat3::zeros(), |m, s| m + s.force * s.branch.transpose())
        / volume
}

#[test]
fn eq18_with_its_products_is_the_contact_stress_where_the_fit_is_exact() {
    let (b, fa) = (deviatoric(0.5), deviatoric(0.8));
    let set: Vec<Sample> = design()
        .into_iter()
        .map(|n| normal_contact(n, 0.01 * (1.0 + quad(&b, &n)), 5.0 * (1.0 + quad(&fa, &n))))
        .collect();
    let volume = 0.3;
    let f = Fabric::of(&set).unwrap();
    let exact = contact_stress(&set, volume);
    let fitted = f.stress(volume);
    assert!(
        max_abs(&(fitted - exact)) < 1e-12 * max_abs(&exact),
        "{fitted} against {exact}"
    );
    // The products matter here: the first order alone is off by a few per cent.
    let first = (Mat3::identity() + (f.a[1] + f.a[3]) * 0.4) * f.pressure(volume);
    assert!(max_abs(&(first - exact)) > 0.01 * max_abs(&exact));
}

#[test]
fn eq19_approaches_eq9_as_the_anisotropy_goes_to_zero() {
    let error = |size: f64| {
        let (b, fa) = (deviatoric(0.6 * size), deviatoric(size));
        let set: Vec<Sample> = design()
            .into_iter()
            .map(|n| normal_contact(n, 0.01 * (1.0 + quad(&b, &n)), 5.0 * (1.0 + quad(&fa, &n))))
            .collect();
        let sigma = contact_stress(&set, 1.0);
        let (p, q) = invariants(&sigma);
        let f = Fabric::of(&set).unwrap();
        let ratio = f.ratio(&deviator(&sigma));
        ((ratio - q / p) / (q / p)).abs()
    };
    let (large, small) = (error(0.5), error(0.05));
    // First order: the relative error shrinks with the anisotropy, about tenfold here.
    assert!(small < 0.01, "{small}");
    assert!(large > 5.0 * small, "{large} {small}");
}

#[test]
fn no_contacts_and_one_sided_forces_are_errors_not_nan() {
    assert!(Fabric::of(&[]).is_err());
    let pulled: Vec<Sample> = design()
        .into_iter()
        .map(|n| normal_contact(n, 0.01, -1.0))
        .collect();
    let e = Fabric::of(&pulled).unwrap_err();
    assert!(e.to_string().contains("force"), "{e}");
    // Ten normals along z and one along x: the second-order density is negative along x.
    let mut aligned = vec![normal_contact(Vec3::z(), 0.01, 1.0); 10];
    aligned.push(normal_contact(Vec3::x(), 0.01, 1.0));
    assert!(Fabric::of(&aligned).is_err());
}
