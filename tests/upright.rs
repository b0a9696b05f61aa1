//! The up axis a surface's shape suggests (`render::upright`): synthetic sheets, disks, rods,
//! balls and model-like shapes, turned and tilted, get the axis the documented rule gives.

use meshflow::render::{Shape, ShapeUp, UpAxis, UpChoice, UpReason};
use meshflow::shapes::{grid, icosphere, Surface};
use nalgebra::{Rotation3, Vector3};

/// The level-4 icosphere stretched by `scale` along x, y, z: an ellipsoid.
fn ellipsoid(scale: [f64; 3]) -> Surface {
    ellipsoid_at_level(4, scale)
}

fn ellipsoid_at_level(level: u32, scale: [f64; 3]) -> Surface {
    let mut sphere = icosphere(level);
    let scale = Vector3::from(scale);
    for p in &mut sphere.positions {
        *p = p.component_mul(&scale);
    }
    sphere
}

/// `surface` turned by `angle_degrees` about `axis` and moved away from the origin.
fn turned(mut surface: Surface, axis: Vector3<f64>, angle_degrees: f64) -> Surface {
    let rotation = Rotation3::from_axis_angle(
        &nalgebra::Unit::new_normalize(axis),
        angle_degrees.to_radians(),
    );
    let offset = Vector3::new(40.0, -7.0, 3.0);
    for p in &mut surface.positions {
        *p = rotation * *p + offset;
    }
    surface
}

fn shape_up(surface: &Surface) -> ShapeUp {
    ShapeUp::of_surface(&surface.positions, &surface.faces).expect("the surface has area")
}

fn choice_for(surface: &Surface) -> UpChoice {
    UpChoice::from_shape(&surface.positions, &surface.faces)
}

fn assert_up(surface: &Surface, shape: Shape, axis: UpAxis) -> ShapeUp {
    let up = shape_up(surface);
    assert_eq!((up.shape, up.axis), (shape, axis), "{up}");
    up
}

#[test]
fn rods_stand_on_their_length() {
    assert_up(&ellipsoid([1.0, 3.0, 1.0]), Shape::Rod, UpAxis::Y);
    assert_up(&ellipsoid([1.0, 1.0, 3.0]), Shape::Rod, UpAxis::Z);
    // A slightly flattened rod is still one (widths 1 and 0.9).
    assert_up(&ellipsoid([0.9, 1.0, 3.0]), Shape::Rod, UpAxis::Z);
}

#[test]
fn sheets_and_disks_lie_flat() {
    // grid() lies in the xy plane: a sheet with normal z; turned about x, its normal is y.
    let sheet = grid(12, 8, 1.5, 1.0);
    assert_up(&sheet, Shape::Sheet, UpAxis::Z);
    let upright = turned(sheet, Vector3::x(), 90.0);
    let up = assert_up(&upright, Shape::Sheet, UpAxis::Y);
    assert!(up.tilt_degrees.unwrap() < 1e-6, "{up}");
    // A cap-like disk (a squashed ball), its normal along z, then along y.
    assert_up(&ellipsoid([3.0, 3.0, 1.0]), Shape::Disk, UpAxis::Z);
    assert_up(&ellipsoid([3.0, 1.0, 2.8]), Shape::Disk, UpAxis::Y);
}

#[test]
fn the_axis_may_tilt_by_up_to_25_degrees() {
    let disk = || ellipsoid([3.0, 3.0, 1.0]);
    let tilted = assert_up(&turned(disk(), Vector3::x(), 20.0), Shape::Disk, UpAxis::Z);
    assert!(
        (tilted.tilt_degrees.unwrap() - 20.0).abs() < 1e-6,
        "{tilted}"
    );
    // 35° from z (55° from y): too far from both, so y as for models.
    let far = assert_up(&turned(disk(), Vector3::x(), 35.0), Shape::Disk, UpAxis::Y);
    assert_eq!(far.nearest, Some(UpAxis::Z));
    assert!((far.tilt_degrees.unwrap() - 35.0).abs() < 1e-6, "{far}");
    // A rod along x is near neither y nor z.
    let rod = assert_up(&ellipsoid([3.0, 1.0, 1.0]), Shape::Rod, UpAxis::Y);
    assert!((rod.tilt_degrees.unwrap() - 90.0).abs() < 1e-6, "{rod}");
}

#[test]
fn balls_keep_z_and_other_shapes_get_y() {
    assert_up(&icosphere(3), Shape::Ball, UpAxis::Z);
    assert_up(&ellipsoid([1.0, 1.05, 1.1]), Shape::Ball, UpAxis::Z);
    // Three distinct spreads (a figure: height y, width x, depth z), even standing along z.
    assert_up(&ellipsoid([1.5, 2.5, 0.8]), Shape::Other, UpAxis::Y);
    assert_up(&ellipsoid([1.5, 0.8, 2.5]), Shape::Other, UpAxis::Y);
}

/// An ellipsoid's surface spreads are not its semi-axes, but their order and the rule's
/// classes follow them; the reported spreads are σ₀/σ₂ ≤ σ₁/σ₂ ≤ 1 and mesh-independent.
#[test]
fn spreads_are_sorted_relative_and_independent_of_the_meshing() {
    let coarse = shape_up(&ellipsoid([1.0, 3.0, 1.0]));
    let fine = shape_up(&ellipsoid_at_level(5, [1.0, 3.0, 1.0]));
    let [a, b, c] = coarse.spreads;
    assert!(a <= b && b <= c && c == 1.0, "{coarse}");
    assert!((a - b).abs() < 1e-3, "a rod of revolution: {coarse}");
    assert!(b < 0.5, "{coarse}");
    for (x, y) in coarse.spreads.iter().zip(fine.spreads) {
        assert!((x - y).abs() < 2e-3, "{coarse} / {fine}");
    }
}

#[test]
fn a_surface_without_area_keeps_z() {
    let points = vec![Vector3::zeros(), Vector3::x(), 2.0 * Vector3::x()];
    assert_eq!(ShapeUp::of_surface(&points, &[[0, 1, 2]]), None);
    assert_eq!(ShapeUp::of_surface(&points, &[]), None);
    // A face naming a missing vertex, or a non-finite one, does not count.
    let broken = vec![
        Vector3::zeros(),
        Vector3::x(),
        Vector3::new(f64::NAN, 1.0, 0.0),
    ];
    assert_eq!(ShapeUp::of_surface(&broken, &[[0, 1, 2], [0, 1, 7]]), None);
    let choice = UpChoice::from_shape(&points, &[[0, 1, 2]]);
    assert_eq!((choice.axis, choice.reason), (UpAxis::Z, UpReason::NoShape));
}

#[test]
fn the_reason_names_the_shape_spreads_and_tilt() {
    let choice = choice_for(&ellipsoid([1.0, 3.0, 1.0]));
    assert_eq!(choice.axis, UpAxis::Y);
    assert_eq!(choice.alternative(), UpAxis::Z);
    let text = choice.reason.to_string();
    assert!(
        text.starts_with("chosen from the data: a rod, spreads 0."),
        "{text}"
    );
    assert!(text.ends_with(" : 1, its axis 0° from y"), "{text}");
    let model = choice_for(&ellipsoid([1.5, 2.5, 0.8]));
    let text = model.reason.to_string();
    assert!(
        text.ends_with(": y as for scanned and exported models"),
        "{text}"
    );
}

/// The faces of the level-4 icosphere (radius 1) whose corners all lie above `z = cut`: a
/// spherical cap of half-angle `acos(cut)` about +z (the other vertices unused).
fn cap(cut: f64) -> Surface {
    let mut sphere = icosphere(4);
    let positions = sphere.positions.clone();
    sphere
        .faces
        .retain(|f| f.iter().all(|&v| positions[v as usize].z > cut));
    sphere
}

/// A cap or sheet is seen along its mean normal from the side it faces: facing
/// `(1 + cos θ)/2` for a cap of half-angle θ, the up axis the nearest signed axis, the eye on
/// the normal exactly.
#[test]
fn caps_and_sheets_are_seen_along_their_axis() {
    let view_of = |surface: &Surface| match choice_for(surface).reason {
        UpReason::Cap(cap) => cap,
        other => panic!("not seen as a cap: {other}"),
    };
    // A cap of about 60° about +z, seen from straight above. Its facing is `(1 + cos θ)/2 =
    // 1 − A/4π` for the half-angle θ of a spherical cap of its area A.
    let sixty_cap = cap(0.5);
    let area: f64 = (sixty_cap.faces.iter())
        .map(|f| {
            let [a, b, c] = f.map(|v| sixty_cap.positions[v as usize]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .sum();
    let sixty = view_of(&sixty_cap);
    let expected = 1.0 - area / (4.0 * std::f64::consts::PI);
    assert!(
        (sixty.facing - expected).abs() < 0.01,
        "{sixty} vs {expected}"
    );
    assert_eq!(sixty.view.up, UpAxis::Z);
    assert!(
        sixty.view.direction().dot(&Vector3::z()) > 1.0 - 1e-9,
        "{sixty}"
    );
    // Turned 17° about x: still z up, the eye 17° off it, on the cap's axis.
    let turned_cap = turned(cap(0.5), Vector3::x(), 17.0);
    let tilted = view_of(&turned_cap);
    assert_eq!(tilted.view.up, UpAxis::Z);
    assert!((tilted.tilt_degrees - 17.0).abs() < 0.5, "{tilted}");
    let axis = Rotation3::from_axis_angle(&Vector3::x_axis(), 17f64.to_radians()) * Vector3::z();
    assert!(tilted.view.direction().dot(&axis) > 1.0 - 1e-4, "{tilted}");
    // Facing down (a cap seen from below, as a yolk under an inverted microscope): -z up.
    let down = view_of(&turned(cap(0.5), Vector3::x(), 180.0));
    assert_eq!(down.view.up, UpAxis::NegZ);
    assert!(down.to_string().contains("from -z"), "{down}");
    assert_eq!(
        choice_for(&turned(cap(0.5), Vector3::x(), 180.0)).view(),
        down.view
    );
    // A flat sheet faces fully.
    assert!((view_of(&grid(12, 8, 1.5, 1.0)).facing - 1.0).abs() < 1e-12);
    // A cap of 127° faces 0.2 of its area one way: the spread rule decides, and a closed
    // surface is never a cap.
    assert!(!matches!(choice_for(&cap(-0.6)).reason, UpReason::Cap(_)));
    assert!(!matches!(
        choice_for(&icosphere(3)).reason,
        UpReason::Cap(_)
    ));
    assert_eq!(
        choice_for(&icosphere(3)).view(),
        meshflow::render::View::default()
    );
}
