//! Headless rendering: silhouettes where the pinhole model puts them, depth order, Lambert
//! shading, flow colours in screen directions and their legend, arrows, perspective-correct
//! interpolation, the fill rule, and errors instead of panics on bad input.

use image::RgbImage;
use meshflow::render::color_wheel::flow_color;
use meshflow::render::colormap::{finite_range, grey, viridis};
use meshflow::render::glyphs::{draw_arrows, glyph_vertices, ArrowStyle};
use meshflow::render::legend::wheel_disc;
use meshflow::render::text::{format_number, format_value};
use meshflow::render::{
    arrow_picture, chart_picture, flow_picture, grey_picture, scalar_picture, write_png, Camera,
    Canvas, Lighting, PictureStyle, RenderError, Surface, UpAxis, View,
};
use meshflow::shapes::{grid, icosphere};
use nalgebra::Vector3;
use std::f64::consts::FRAC_1_SQRT_2;

const FOV: f64 = 30.0;

fn unlit() -> PictureStyle {
    PictureStyle {
        lighting: Lighting::unlit(),
        ..PictureStyle::default()
    }
}

/// Pixel `(x, y)` as RGB in [0, 1].
fn pixel(image: &RgbImage, x: u32, y: u32) -> [f64; 3] {
    image.get_pixel(x, y).0.map(|c| c as f64 / 255.0)
}

fn is_background(image: &RgbImage, x: u32, y: u32) -> bool {
    image.get_pixel(x, y).0 == [255; 3]
}

fn max_difference(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f64::max)
}

/// The unit icosphere (level 4) moved by `offset`.
fn sphere_at(offset: Vector3<f64>) -> (Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let sphere = icosphere(4);
    let faces = sphere.mesh().expect("valid").faces().to_vec();
    (sphere.positions.iter().map(|p| p + offset).collect(), faces)
}

/// The surface drawn in one grey value.
fn uniform_grey(
    camera: &Camera,
    positions: &[Vector3<f64>],
    faces: &[[u32; 3]],
    value: f64,
    style: &PictureStyle,
) -> RgbImage {
    let surface = Surface { positions, faces };
    let grey_values = vec![value; positions.len()];
    grey_picture(camera, surface, &grey_values, (0.0, 1.0), style).unwrap()
}

/// A canvas with the surface drawn white under the default light.
fn white_surface(camera: &Camera, positions: &[Vector3<f64>], faces: &[[u32; 3]]) -> Canvas {
    let mut canvas = Canvas::for_camera(camera, 3);
    let white = vec![[1.0; 3]; positions.len()];
    canvas
        .draw_mesh(camera, positions, faces, &white, &Lighting::default())
        .unwrap();
    canvas
}

/// Looks along +y from `(0, −distance, 0)` with +z up: right = +x, down = −z.
fn camera_from_front(distance: f64, width: u32, height: u32) -> Camera {
    Camera::look_at(
        Vector3::new(0.0, -distance, 0.0),
        Vector3::zeros(),
        Vector3::z(),
        FOV,
        width,
        height,
    )
    .expect("valid camera")
}

/// Unit direction of the ray from `(0, −d, 0)` through the point `(x, y)` of the picture of
/// [`camera_from_front`], built from the pinhole model by hand.
fn front_ray(x: f64, y: f64, width: u32, height: u32) -> Vector3<f64> {
    let focal = height as f64 / 2.0 / (FOV / 2.0).to_radians().tan();
    Vector3::new(
        (x - width as f64 / 2.0) / focal,
        1.0,
        -(y - height as f64 / 2.0) / focal,
    )
    .normalize()
}

/// Where the ray from `eye` along unit `direction` first meets the unit sphere about `centre`.
fn hit_sphere(
    eye: &Vector3<f64>,
    direction: &Vector3<f64>,
    centre: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let to_eye = eye - centre;
    let b = direction.dot(&to_eye);
    let discriminant = b * b - (to_eye.norm_squared() - 1.0);
    (discriminant >= 0.0).then(|| eye + (-b - discriminant.sqrt()) * direction)
}

#[test]
fn sphere_silhouette_is_the_projected_circle() {
    let (width, height, distance) = (160, 120, 4.0);
    let (positions, faces) = sphere_at(Vector3::zeros());
    let camera = camera_from_front(distance, width, height);
    let image = uniform_grey(&camera, &positions, &faces, 0.5, &unlit());
    let radius =
        height as f64 / 2.0 * (1.0 / distance).asin().tan() / (FOV / 2.0).to_radians().tan();
    assert!((radius - 57.82).abs() < 0.01, "radius {radius}");
    let (mut inside, mut outside) = (0, 0);
    for (x, y, _) in image.enumerate_pixels() {
        let r = (x as f64 + 0.5 - 80.0).hypot(y as f64 + 0.5 - 60.0);
        if r <= 0.95 * radius {
            assert!(
                !is_background(&image, x, y),
                "pixel ({x}, {y}) at r = {r} is background"
            );
            inside += 1;
        } else if r >= 1.05 * radius {
            assert!(
                is_background(&image, x, y),
                "pixel ({x}, {y}) at r = {r} is surface"
            );
            outside += 1;
        }
    }
    assert!(inside > 9000 && outside > 3000, "{inside} {outside}");
}

#[test]
fn off_centre_sphere_lands_where_projected() {
    let (width, height, distance) = (160, 120, 6.0);
    let centre = Vector3::new(1.2, 0.0, 0.6); // right of and above the view axis
    let (positions, faces) = sphere_at(centre);
    let camera = camera_from_front(distance, width, height);
    let image = uniform_grey(&camera, &positions, &faces, 0.5, &unlit());
    // The centre's projection by hand: x = W/2 + F·1.2/6, y = H/2 − F·0.6/6.
    let focal = 60.0 / (15f64).to_radians().tan();
    let [px, py, depth] = camera.project(&centre).unwrap();
    assert!((px - (80.0 + focal * 0.2)).abs() < 1e-9 && (py - (60.0 - focal * 0.1)).abs() < 1e-9);
    assert!((depth - 6.0).abs() < 1e-12);
    // Every pixel ray passing the centre closer than 0.97 hits the surface, farther than 1.03
    // misses it.
    let eye = Vector3::new(0.0, -distance, 0.0);
    let mut checked = 0;
    for (x, y, _) in image.enumerate_pixels() {
        let ray = front_ray(x as f64 + 0.5, y as f64 + 0.5, width, height);
        let miss = (centre - eye).cross(&ray).norm();
        if miss <= 0.97 {
            assert!(
                !is_background(&image, x, y),
                "pixel ({x}, {y}) passes at {miss}"
            );
            checked += 1;
        } else if miss >= 1.03 {
            assert!(
                is_background(&image, x, y),
                "pixel ({x}, {y}) passes at {miss}"
            );
        }
    }
    assert!(checked > 2000, "{checked}");
    assert!(
        is_background(&image, 80, 60),
        "the image centre is off the sphere"
    );
}

#[test]
fn framing_fits_the_bounding_sphere_in_the_smaller_extent() {
    let (positions, faces) = sphere_at(Vector3::new(3.0, -2.0, 1.0));
    let (width, height) = (200, 100);
    let camera = Camera::framing(&positions, View::new(20.0, 10.0), width, height);
    let [x, y, _] = camera.project(&Vector3::new(3.0, -2.0, 1.0)).unwrap();
    assert!((x - 100.0).abs() < 1e-9 && (y - 50.0).abs() < 1e-9);
    let image = uniform_grey(&camera, &positions, &faces, 0.5, &unlit());
    // The silhouette radius is 0.88 of the half-height (44 px); the bounding sphere of the
    // icosphere's vertices is the unit sphere.
    for (x, y, _) in image.enumerate_pixels() {
        let r = (x as f64 + 0.5 - 100.0).hypot(y as f64 + 0.5 - 50.0);
        if r <= 0.95 * 44.0 {
            assert!(!is_background(&image, x, y), "({x}, {y})");
        } else if r >= 1.05 * 44.0 {
            assert!(is_background(&image, x, y), "({x}, {y})");
        }
    }
}

#[test]
fn nearer_triangle_wins_regardless_of_draw_order() {
    let camera = camera_from_front(4.0, 64, 48);
    // Two overlapping triangles facing the camera: near (depth 3, red) and a larger far one
    // (depth 5, blue) that shows around it.
    let triangle = |y: f64, size: f64| {
        [
            Vector3::new(-size, y, -size),
            Vector3::new(size, y, -size),
            Vector3::new(0.0, y, size),
        ]
    };
    let positions: Vec<Vector3<f64>> = triangle(-1.0, 0.5)
        .into_iter()
        .chain(triangle(1.0, 2.0))
        .collect();
    let colours = [[1.0, 0.0, 0.0]; 3]
        .into_iter()
        .chain([[0.0, 0.0, 1.0]; 3])
        .collect::<Vec<_>>();
    let (near, far) = ([0, 1, 2], [3, 4, 5]);
    let (red, blue) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let check = |image: RgbImage| {
        assert_eq!(pixel(&image, 32, 24), red);
        assert_eq!(
            pixel(&image, 32, 3),
            blue,
            "the far triangle above the near one"
        );
    };
    for faces in [vec![near, far], vec![far, near]] {
        let mut canvas = Canvas::for_camera(&camera, 3);
        canvas
            .draw_mesh(&camera, &positions, &faces, &colours, &Lighting::unlit())
            .unwrap();
        check(canvas.finish());
    }
    // Also across separate draw calls, in both orders.
    for order in [[near, far], [far, near]] {
        let mut canvas = Canvas::for_camera(&camera, 3);
        for face in order {
            canvas
                .draw_mesh(&camera, &positions, &[face], &colours, &Lighting::unlit())
                .unwrap();
        }
        check(canvas.finish());
    }
}

#[test]
fn lambert_shading_follows_the_cosine_to_the_headlight() {
    let (width, height, distance) = (120, 120, 4.0);
    let (positions, faces) = sphere_at(Vector3::zeros());
    let camera = camera_from_front(distance, width, height);
    let style = PictureStyle {
        lighting: Lighting::headlight(0.0, 1.0),
        ..PictureStyle::default()
    };
    let image = uniform_grey(&camera, &positions, &faces, 1.0, &style);
    let eye = Vector3::new(0.0, -distance, 0.0);
    // Expected: |n · l| with l = −forward = −y, averaged over the pixel's 3 × 3 sample rays.
    let expected = |x: u32, y: u32| {
        let mut sum = 0.0;
        for (i, j) in (0..3).flat_map(|i| (0..3).map(move |j| (i, j))) {
            let ray = front_ray(
                x as f64 + (i as f64 + 0.5) / 3.0,
                y as f64 + (j as f64 + 0.5) / 3.0,
                width,
                height,
            );
            sum += hit_sphere(&eye, &ray, &Vector3::zeros()).map_or(1.0, |p| p.y.abs());
        }
        sum / 9.0
    };
    let centre = pixel(&image, 60, 60)[0];
    assert!((centre - 1.0).abs() < 0.006, "centre {centre}");
    let radius = 60.0 * (0.25f64).asin().tan() / (15f64).to_radians().tan(); // 57.8 px
    for (dx, dy) in [
        (1.0, 0.0),
        (-1.0, 0.0),
        (0.0, 1.0),
        (0.0, -1.0),
        (FRAC_1_SQRT_2, FRAC_1_SQRT_2),
    ] {
        let (x, y) = (
            (60.0 + 0.9 * radius * dx) as u32,
            (60.0 + 0.9 * radius * dy) as u32,
        );
        let (value, cosine) = (pixel(&image, x, y)[0], expected(x, y));
        assert!(cosine < 0.65, "a pixel near the limb ({cosine})");
        assert!(
            (value - cosine).abs() < 0.006,
            "({x}, {y}): {value} vs cos = {cosine}"
        );
        let ratio = centre / value;
        assert!(
            (ratio - 1.0 / cosine).abs() < 0.03 / cosine,
            "ratio {ratio} vs {}",
            1.0 / cosine
        );
    }
}

/// Flow of a rotation with angular velocity `omega` about +z, the camera's up axis.
fn turning(positions: &[Vector3<f64>], omega: f64) -> Vec<Vector3<f64>> {
    positions
        .iter()
        .map(|p| omega * Vector3::z().cross(p))
        .collect()
}

/// Chromaticity: the colour divided by its largest channel.
fn hue(colour: [f64; 3]) -> [f64; 3] {
    let largest = colour.iter().copied().fold(0.0, f64::max);
    colour.map(|c| c / largest)
}

#[test]
fn flow_colours_show_screen_directions() {
    let (width, height, distance) = (160, 120, 4.0);
    let (positions, faces) = sphere_at(Vector3::zeros());
    let camera = camera_from_front(distance, width, height);
    let surface = Surface {
        positions: &positions,
        faces: &faces,
    };
    // Seen from the front, the near side of the sphere turning about +z moves along +x: right.
    let front = Vector3::new(0.0, -1.0, 0.0);
    assert_eq!(
        camera.screen_components(&Vector3::z().cross(&front)),
        [1.0, 0.0]
    );
    let omega = 0.3;
    for (sign, expected) in [(1.0, flow_color(1.0, 0.0)), (-1.0, flow_color(-1.0, 0.0))] {
        let flow = turning(&positions, sign * omega);
        // Shaded as usual: the centre pixel has the hue of (±1, 0), red resp. cyan-blue.
        let shaded =
            flow_picture(&camera, surface, &flow, omega, &PictureStyle::default()).unwrap();
        let centre = hue(pixel(&shaded, 80, 60));
        // Rightward motion crosses +u, where the closed wheel has no seam: all channels match.
        assert!(
            max_difference(centre, hue(expected)) < 0.03,
            "{centre:?} vs {expected:?}"
        );
        // Unlit, along the vertical centre line: speed ω |p_y| at the point seen, colour
        // flow_color(−sign · p_y, 0) (v = 0 as the flow is horizontal).
        let image = flow_picture(&camera, surface, &flow, omega, &unlit()).unwrap();
        let eye = Vector3::new(0.0, -distance, 0.0);
        // (Rows above the legend's label, on the bottom line from x = 39 to 127.)
        for y in (8..=104).step_by(4) {
            let p = hit_sphere(
                &eye,
                &front_ray(80.5, y as f64 + 0.5, width, height),
                &Vector3::zeros(),
            )
            .unwrap();
            let expected = flow_color(-sign * p.y, 0.0);
            let actual = pixel(&image, 80, y);
            for c in 0..3 {
                assert!(
                    (actual[c] - expected[c]).abs() < 0.01,
                    "y = {y}: {actual:?} vs {expected:?}"
                );
            }
        }
    }
}

#[test]
fn legend_disc_is_the_colour_key_in_screen_directions() {
    let (positions, faces) = sphere_at(Vector3::zeros());
    let camera = Camera::framing(&positions, View::default(), 400, 300);
    let surface = Surface {
        positions: &positions,
        faces: &faces,
    };
    let image = flow_picture(
        &camera,
        surface,
        &turning(&positions, 1.0),
        1.0,
        &PictureStyle::default(),
    )
    .unwrap();
    let disc = wheel_disc(400, 300);
    assert!((disc.radius - 33.0).abs() < 1e-9);
    let [cx, cy] = disc.centre;
    let sample = |dx: f64, dy: f64| {
        let (x, y) = ((cx + dx).floor(), (cy + dy).floor());
        let (u, v) = ((x + 0.5 - cx) / disc.radius, (y + 0.5 - cy) / disc.radius);
        (pixel(&image, x as u32, y as u32), flow_color(u, v))
    };
    let r = disc.radius;
    // Off the cross-hairs, every pixel is flow_color of its offset over the radius.
    for (dx, dy) in [
        (0.5 * r, 3.0),
        (-0.5 * r, 3.0),
        (3.0, -0.5 * r),
        (3.0, 0.5 * r),
        (0.5 * r, -0.5 * r),
        (-0.3 * r, 0.6 * r),
        (0.9 * r, 4.0),
    ] {
        let (actual, expected) = sample(dx, dy);
        assert!(
            max_difference(actual, expected) < 0.01,
            "({dx}, {dy}): {actual:?} vs {expected:?}"
        );
    }
    // Right of the centre: red-ish; above: violet (blue first); left: cyan-blue; below: yellow.
    let (right, _) = sample(0.7 * r, 3.0);
    assert!(
        right[0] > 0.95 && right[1] < 0.5 && right[2] < 0.5,
        "{right:?}"
    );
    let (above, _) = sample(3.0, -0.7 * r);
    assert!(
        above[2] > 0.95 && above[0] < 0.8 && above[1] < 0.5,
        "{above:?}"
    );
    let (left, _) = sample(-0.7 * r, 3.0);
    assert!(left[2] > 0.95 && left[1] > 0.8 && left[0] < 0.5, "{left:?}");
    let (below, _) = sample(3.0, 0.7 * r);
    assert!(
        below[0] > 0.95 && below[1] > 0.8 && below[2] < 0.5,
        "{below:?}"
    );
    // Just outside the outline: background.
    assert!(is_background(&image, (cx + r + 3.0) as u32, cy as u32));
}

/// A `side × side`-pixel square facing the camera of a `picture × picture` picture, cut into
/// `cells × cells` grid squares, whose vertex `(i, j)` projects to the pixel position
/// `first + (i, j) · side / cells` (row-major from the top-left corner).
fn square_facing_camera(
    picture: u32,
    cells: usize,
    first: f64,
    side: f64,
) -> (Camera, Vec<Vector3<f64>>, Vec<[u32; 3]>) {
    let distance = 5.0;
    let eye = Vector3::new(0.0, 0.0, distance);
    let camera = Camera::look_at(eye, Vector3::zeros(), Vector3::y(), FOV, picture, picture);
    let half = picture as f64 / 2.0;
    let focal = half / (FOV / 2.0).to_radians().tan();
    let to_world = |pixels: f64| pixels * distance / focal;
    let square = grid(cells, cells, to_world(side), to_world(side));
    // Vertex (0, 0) at pixel (first, first): world x = (first − W/2)·d/F and, as down is −y,
    // world y = (H/2 − first)·d/F; the grid's y runs up, so flip it.
    let positions = square
        .positions
        .iter()
        .map(|p| {
            Vector3::new(
                to_world(first - half) + p.x,
                to_world(half - first) - p.y,
                0.0,
            )
        })
        .collect();
    (camera.unwrap(), positions, square.faces)
}

fn is_dark(image: &RgbImage, x: u32, y: u32) -> bool {
    image.get_pixel(x, y).0.iter().all(|&c| c < 128)
}

#[test]
fn arrows_are_spaced_by_cells_and_point_along_the_flow() {
    let (camera, positions, faces) = square_facing_camera(280, 9, 14.5, 252.0);
    for (i, p) in positions.iter().enumerate().take(12) {
        let [x, y, _] = camera.project(p).unwrap();
        let expected = [14.5 + 28.0 * (i % 10) as f64, 14.5 + 28.0 * (i / 10) as f64];
        assert!(
            (x - expected[0]).abs() < 1e-9 && (y - expected[1]).abs() < 1e-9,
            "{i}: ({x}, {y})"
        );
    }
    let scale = 0.2;
    let flow = vec![Vector3::new(scale, 0.0, 0.0); positions.len()]; // screen right
    let surface = Surface {
        positions: &positions,
        faces: &faces,
    };
    let style = PictureStyle::default(); // spacing 28
    let image = arrow_picture(
        &camera,
        surface,
        &vec![1.0; positions.len()],
        (0.0, 1.0),
        &flow,
        scale,
        &style,
    )
    .unwrap();
    let length = 0.9 * 28.0;
    for j in 0..9 {
        let y = 14 + 28 * j;
        // Dark runs along the shafts' row.
        let mut runs = Vec::new();
        let mut x = 0;
        while x < 280 {
            if is_dark(&image, x, y) {
                let start = x;
                while x < 280 && is_dark(&image, x, y) {
                    x += 1;
                }
                runs.push((start, x));
            }
            x += 1;
        }
        assert!(runs.len() >= 9, "row {y}: runs {runs:?}");
        for (i, &(start, end)) in runs.iter().take(9).enumerate() {
            let from = 14.5 + 28.0 * i as f64;
            assert!(
                (start as f64 - from).abs() <= 1.0,
                "row {y} arrow {i}: starts at {start}"
            );
            assert!(
                (end as f64 - (from + length)).abs() <= 1.5,
                "row {y} arrow {i}: ends at {end}"
            );
            // Off the shaft (2 pixels above and below its axis) only the head is dark: it sits
            // at the tip, so the arrow points right.
            let off_shaft: Vec<u32> = (start..end.min(280))
                .filter(|&x| [y - 2, y + 2].iter().any(|&yy| !is_light(&image, x, yy)))
                .collect();
            assert!(!off_shaft.is_empty(), "row {y} arrow {i}: no head");
            assert!(
                off_shaft.iter().all(|&x| x as f64 >= from + 0.6 * length),
                "row {y} arrow {i}: {off_shaft:?}"
            );
        }
    }
}

/// Light: the white (shaded) surface or background rather than an arrow.
fn is_light(image: &RgbImage, x: u32, y: u32) -> bool {
    image.get_pixel(x, y).0.iter().all(|&c| c > 200)
}

#[test]
fn no_arrows_on_the_far_side() {
    let (positions, faces) = sphere_at(Vector3::zeros());
    let camera = camera_from_front(4.0, 160, 120);
    let canvas = white_surface(&camera, &positions, &faces);
    let chosen = glyph_vertices(&canvas, &camera, &positions, &faces, 12.0);
    assert!(chosen.len() > 50, "{}", chosen.len());
    // Near side: y < 0 (the eye is at y = −4); and facing the camera clearly.
    assert!(
        chosen.iter().all(|&v| positions[v].y < -0.1),
        "a far-side or limb vertex was chosen"
    );
    // Flow only on the far half: no arrow, no dark pixel. On the near half: arrows.
    let dark_pixels = |near: bool| {
        let flow: Vec<Vector3<f64>> = positions
            .iter()
            .map(|p| {
                if (p.y < 0.0) == near {
                    Vector3::z().cross(p)
                } else {
                    Vector3::zeros()
                }
            })
            .collect();
        let mut with_arrows = canvas.clone();
        let style = ArrowStyle::default();
        let drawn = draw_arrows(
            &mut with_arrows,
            &camera,
            &positions,
            &faces,
            &flow,
            1.0,
            &style,
        );
        let image = with_arrows.finish();
        let dark = image
            .pixels()
            .filter(|p| p.0.iter().all(|&c| c < 60))
            .count();
        (drawn.unwrap(), dark)
    };
    assert_eq!(dark_pixels(false), (0, 0));
    let (drawn, dark) = dark_pixels(true);
    assert!(
        drawn > 10 && dark > 10 * drawn,
        "{drawn} arrows, {dark} dark pixels"
    );
}

#[test]
fn draw_arrows_counts_and_skips_tiny_arrows() {
    let (camera, positions, faces) = square_facing_camera(280, 9, 14.5, 252.0);
    let mut canvas = white_surface(&camera, &positions, &faces);
    let style = ArrowStyle::default();
    // Scale 1: a vector of length 1e-3 is 0.0252 px long: skipped; length 1 is drawn.
    let mut flow = vec![Vector3::new(1e-3, 0.0, 0.0); positions.len()];
    flow[55] = Vector3::new(0.0, 1.0, 0.0);
    flow[56] = Vector3::new(f64::NAN, 0.0, 0.0);
    let drawn = draw_arrows(&mut canvas, &camera, &positions, &faces, &flow, 1.0, &style).unwrap();
    assert_eq!(drawn, 1);
}

#[test]
fn perspective_correct_interpolation_of_a_slanted_plane() {
    // Camera at the origin looking down −z, +y up; a quad from depth 2 (t = 0, red 0) to depth
    // 8 (t = 1, red 1), red linear in world space along it.
    let (width, height) = (101, 101);
    let camera = Camera::look_at(
        Vector3::zeros(),
        -Vector3::z(),
        Vector3::y(),
        60.0,
        width,
        height,
    )
    .unwrap();
    let positions = vec![
        Vector3::new(-1.0, -1.0, -2.0),
        Vector3::new(1.0, -1.0, -2.0),
        Vector3::new(1.0, 1.0, -8.0),
        Vector3::new(-1.0, 1.0, -8.0),
    ];
    let colours = vec![[0.0; 3], [0.0; 3], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]];
    let mut canvas = Canvas::for_camera(&camera, 3);
    canvas
        .draw_mesh(
            &camera,
            &positions,
            &[[0, 1, 2], [0, 2, 3]],
            &colours,
            &Lighting::unlit(),
        )
        .unwrap();
    let image = canvas.finish();
    // World midpoint (0, 0, −5): colour 0.5, seen at the picture's centre pixel (50, 50);
    // interpolating affinely on the screen instead gives 0.67 there.
    let [x, y, _] = camera.project(&Vector3::new(0.0, 0.0, -5.0)).unwrap();
    assert!((x - 50.5).abs() < 1e-12 && (y - 50.5).abs() < 1e-12);
    let centre = pixel(&image, 50, 50)[0];
    assert!((centre - 0.5).abs() < 0.006, "centre {centre}");
    // Every row: the point P(t) = (0, −1 + 2t, −2 − 6t) is seen at row offset
    // s = (y − H/2)/F = (1 − 2t)/(2 + 6t), so t = (1 − 2s)/(2 + 6s).
    let focal = 50.5 / (30f64).to_radians().tan();
    let mut rows = 0;
    for row in 0..height {
        let s = (row as f64 + 0.5 - 50.5) / focal;
        let t = (1.0 - 2.0 * s) / (2.0 + 6.0 * s);
        if (0.02..=0.98).contains(&t) {
            let red = pixel(&image, 50, row)[0];
            assert!((red - t).abs() < 0.006, "row {row}: {red} vs t = {t}");
            rows += 1;
        }
    }
    assert!(rows > 45, "{rows}");
}

#[test]
fn shared_edges_have_no_cracks_and_no_overlap() {
    // A fronto-parallel square whose grid vertices project onto pixel centres (10.5 + 4 k):
    // all edges pass through sample centres. Supersample 1, top-left rule: exactly the 40 × 40
    // pixels with centres in [10.5, 50.5) are covered.
    let (camera, positions, faces) = square_facing_camera(64, 10, 10.5, 40.0);
    let mut canvas = Canvas::for_camera(&camera, 1);
    canvas
        .draw_mesh(
            &camera,
            &positions,
            &faces,
            &vec![[1.0, 0.0, 0.0]; positions.len()],
            &Lighting::unlit(),
        )
        .unwrap();
    let image = canvas.finish();
    for (x, y, p) in image.enumerate_pixels() {
        let inside = (10..50).contains(&x) && (10..50).contains(&y);
        assert_eq!(
            p.0,
            if inside { [255, 0, 0] } else { [255; 3] },
            "({x}, {y})"
        );
    }
}

#[test]
fn camera_conventions() {
    let camera = camera_from_front(4.0, 100, 80);
    assert_eq!(camera.screen_components(&Vector3::x()), [1.0, 0.0]);
    assert_eq!(camera.screen_components(&Vector3::z()), [0.0, -1.0]);
    // The projection moves along the screen components (exactly at the picture's centre).
    let p = Vector3::zeros();
    let v = Vector3::new(0.3, 0.7, -0.2);
    let [x0, y0, _] = camera.project(&p).unwrap();
    let [x1, y1, _] = camera.project(&(p + 1e-6 * v)).unwrap();
    let [a, b] = camera.screen_components(&v);
    let factor = camera.focal_length() / 4.0 * 1e-6;
    assert!(((x1 - x0) - factor * a).abs() < 1e-9 && ((y1 - y0) - factor * b).abs() < 1e-9);
    assert_eq!(
        camera.project(&Vector3::new(0.0, -5.0, 0.0)),
        None,
        "behind the eye"
    );
    // Views: azimuth from +x towards +y, elevation towards +z.
    let direction = |a, e| View::new(a, e).direction();
    assert!((direction(0.0, 0.0) - Vector3::x()).norm() < 1e-15);
    assert!((direction(90.0, 0.0) - Vector3::y()).norm() < 1e-15);
    assert!((direction(33.0, 90.0) - Vector3::z()).norm() < 1e-15);
    assert_eq!(
        View::default(),
        View {
            azimuth_degrees: -60.0,
            elevation_degrees: 30.0,
            roll_degrees: 0.0,
            up: UpAxis::Z,
        }
    );
    // Straight down: up falls back to +y, so +x is right and +y is up on the screen.
    let top = Camera::framing(&[Vector3::zeros()], View::new(0.0, 90.0), 50, 50);
    assert_eq!(
        top.screen_components(&Vector3::x()).map(f64::round),
        [1.0, 0.0]
    );
    assert_eq!(
        top.screen_components(&Vector3::y()).map(f64::round),
        [0.0, -1.0]
    );
}

#[test]
fn views_parse_from_text() {
    assert_eq!(" -60 , 30 ".parse::<View>().unwrap(), View::default());
    assert_eq!("10,-5.5".parse::<View>().unwrap(), View::new(10.0, -5.5));
    assert_eq!(
        "10, 20, -90".parse::<View>().unwrap(),
        View {
            roll_degrees: -90.0,
            ..View::new(10.0, 20.0)
        }
    );
    for bad in ["", "10", "1,2,3,4", "a,2", "1,nan", "inf,0", "1,2,x"] {
        let error = bad.parse::<View>().unwrap_err();
        assert!(
            matches!(error, RenderError::View { .. }),
            "{bad:?}: {error:?}"
        );
        assert!(error.to_string().contains("AZIMUTH,ELEVATION"));
    }
}

#[test]
fn up_axes_are_the_rotated_standard_frame() {
    use nalgebra::Rotation3;
    for up in UpAxis::ALL {
        let [h1, h2, u] = up.frame();
        assert_eq!(up.name().parse::<UpAxis>().unwrap(), up);
        assert_eq!(u, up.vector());
        // The smallest rotation taking +z to the up axis (a half turn about +x for −z) maps
        // (x, y, z) onto the frame.
        let rotation = match up {
            UpAxis::NegZ => Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI),
            _ => Rotation3::rotation_between(&Vector3::z(), &u).unwrap(),
        };
        for (axis, expected) in [(Vector3::x(), h1), (Vector3::y(), h2), (Vector3::z(), u)] {
            assert!(
                (rotation * axis - expected).norm() < 1e-15,
                "{up}: {axis} -> {expected}"
            );
        }
        assert_eq!(h1.cross(&h2), u, "{up}: right-handed");
    }
    assert_eq!("+Y".parse::<UpAxis>().unwrap(), UpAxis::Y);
    assert_eq!(" -x".parse::<UpAxis>().unwrap(), UpAxis::NegX);
    for bad in ["", "w", "--y", "xy"] {
        let error = bad.parse::<UpAxis>().unwrap_err().to_string();
        assert!(error.contains("x, y, z, -x, -y, -z"), "{bad:?}: {error}");
    }
}

#[test]
fn y_up_views_show_y_up_on_the_screen() {
    let points = [Vector3::new(-1.0, -2.0, -0.5), Vector3::new(1.0, 2.0, 0.5)];
    let default_y_up = View::default().with_up(UpAxis::Y);
    let (c, s) = (30f64.to_radians().cos(), 0.5);
    // Azimuth −60° from +x towards −z, elevation 30° towards +y.
    let expected = Vector3::new(c * 0.5, s, c * 60f64.to_radians().sin());
    assert!((default_y_up.direction() - expected).norm() < 1e-15);
    let camera = Camera::framing(&points, default_y_up, 96, 72);
    let close =
        |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
    // +y points straight up on the screen (y grows downward), +x right and a little down,
    // +z (towards the eye) left and down.
    assert!(close(camera.screen_components(&Vector3::y()), [0.0, -c]));
    assert!(close(camera.screen_components(&Vector3::x()), [c, 0.25]));
    assert!(close(
        camera.screen_components(&Vector3::z()),
        [-0.5, 0.5 * c]
    ));
    // The same angles about +z see a z-up model exactly as they see its y-up export
    // (x, y, z) ↦ (x, z, −y).
    let z_up = Camera::framing(&points, View::default(), 96, 72);
    let export = |v: Vector3<f64>| Vector3::new(v.x, v.z, -v.y);
    for v in [
        Vector3::x(),
        Vector3::y(),
        Vector3::z(),
        Vector3::new(0.3, -0.7, 0.2),
    ] {
        assert!(close(
            z_up.screen_components(&v),
            camera.screen_components(&export(v))
        ));
    }
    // Looking straight down −y from above: h₂ = −z is up on the screen, +x right.
    let top = Camera::framing(&points, View::new(10.0, 90.0).with_up(UpAxis::Y), 50, 50);
    assert!(close(top.screen_components(&Vector3::z()), [0.0, 1.0]));
    assert!(close(top.screen_components(&Vector3::x()), [1.0, 0.0]));
}

#[test]
fn roll_turns_the_picture_counter_clockwise() {
    let points = [Vector3::zeros(), Vector3::new(1.0, 1.0, 1.0)];
    let plain = Camera::framing(&points, View::default(), 80, 60);
    let unrolled = View {
        roll_degrees: 0.0,
        ..View::default()
    };
    assert_eq!(Camera::framing(&points, unrolled, 80, 60), plain);
    let rolled = |degrees: f64| {
        let view = View {
            roll_degrees: degrees,
            ..View::default()
        };
        Camera::framing(&points, view, 80, 60)
    };
    let up = plain.screen_components(&Vector3::z());
    assert!(up[0].abs() < 1e-15 && up[1] < 0.0, "{up:?}");
    // At 90° the up axis points left, at −90° right; the eye does not move.
    let left = rolled(90.0).screen_components(&Vector3::z());
    assert!(
        (left[0] - up[1]).abs() < 1e-12 && left[1].abs() < 1e-12,
        "{left:?}"
    );
    let right = rolled(-90.0).screen_components(&Vector3::z());
    assert!(
        (right[0] + up[1]).abs() < 1e-12 && right[1].abs() < 1e-12,
        "{right:?}"
    );
    assert_eq!(rolled(90.0).eye(), plain.eye());
    assert!((rolled(90.0).forward() - plain.forward()).norm() < 1e-15);
}

#[test]
fn bad_input_gives_render_errors() {
    let (positions, faces) = sphere_at(Vector3::zeros());
    let n = positions.len();
    let camera = camera_from_front(4.0, 40, 30);
    let surface = Surface {
        positions: &positions,
        faces: &faces,
    };
    let style = PictureStyle::default();
    let short = vec![0.5; n - 1];
    let flow = vec![Vector3::zeros(); n];
    let mismatch = |e: RenderError| matches!(e, RenderError::CountMismatch { expected, got, .. } if expected == n && got == n - 1);
    assert!(mismatch(
        grey_picture(&camera, surface, &short, (0.0, 1.0), &style).unwrap_err()
    ));
    assert!(mismatch(
        scalar_picture(&camera, surface, &short, (0.0, 1.0), &style).unwrap_err()
    ));
    assert!(mismatch(
        flow_picture(&camera, surface, &flow[1..], 1.0, &style).unwrap_err()
    ));
    assert!(mismatch(
        arrow_picture(
            &camera,
            surface,
            &vec![0.5; n],
            (0.0, 1.0),
            &flow[1..],
            1.0,
            &style
        )
        .unwrap_err()
    ));
    assert!(matches!(
        chart_picture(3, 4, &[[0.0; 3]; 11], 2),
        Err(RenderError::CountMismatch {
            expected: 12,
            got: 11,
            ..
        })
    ));
    assert!(matches!(
        chart_picture(3, 4, &[[0.0; 3]; 12], 0),
        Err(RenderError::Size { .. })
    ));
    // Scales, ranges, faces.
    assert!(matches!(
        flow_picture(&camera, surface, &flow, 0.0, &style),
        Err(RenderError::InvalidParameter {
            name: "flow scale",
            ..
        })
    ));
    assert!(matches!(
        flow_picture(&camera, surface, &flow, f64::NAN, &style),
        Err(RenderError::InvalidParameter { .. })
    ));
    assert!(matches!(
        grey_picture(&camera, surface, &vec![0.5; n], (1.0, 0.0), &style),
        Err(RenderError::Range { .. })
    ));
    assert!(matches!(
        scalar_picture(
            &camera,
            surface,
            &vec![0.5; n],
            (0.0, f64::INFINITY),
            &style
        ),
        Err(RenderError::Range { .. })
    ));
    let bad_faces = [[0, 1, n as u32]];
    let bad = Surface {
        positions: &positions,
        faces: &bad_faces,
    };
    let error = grey_picture(&camera, bad, &vec![0.5; n], (0.0, 1.0), &style).unwrap_err();
    assert!(matches!(error, RenderError::Faces(_)), "{error:?}");
    assert!(error.to_string().contains("face 0"), "{error}");
    // Cameras.
    let look = |eye: Vector3<f64>, fov: f64, w: u32| {
        Camera::look_at(eye, Vector3::zeros(), Vector3::z(), fov, w, 10)
    };
    for attempt in [
        look(Vector3::zeros(), 30.0, 10),
        look(Vector3::x(), 180.0, 10),
        look(Vector3::x(), 30.0, 0),
        look(Vector3::new(f64::NAN, 0.0, 0.0), 30.0, 10),
    ] {
        assert!(
            matches!(attempt, Err(RenderError::Camera { .. })),
            "{attempt:?}"
        );
    }
    // A canvas of another size than the camera's picture.
    let mut canvas = Canvas::new(41, 30, 1);
    let colours = vec![[0.5; 3]; n];
    assert!(matches!(
        canvas.draw_mesh(&camera, &positions, &faces, &colours, &Lighting::default()),
        Err(RenderError::Size { .. })
    ));
    // The crate's error wraps it.
    let error = flow_picture(&camera, surface, &flow, -1.0, &style).unwrap_err();
    let top: meshflow::Error = error.into();
    assert!(top.to_string().contains("flow scale = -1"), "{top}");
}

#[test]
fn non_finite_positions_and_values_do_not_panic() {
    let (mut positions, faces) = sphere_at(Vector3::zeros());
    let n = positions.len();
    positions[0] = Vector3::new(f64::NAN, 0.0, 0.0);
    positions[1] = Vector3::new(f64::INFINITY, 1.0, 0.0);
    let camera = camera_from_front(4.0, 80, 60);
    let surface = Surface {
        positions: &positions,
        faces: &faces,
    };
    let mut values: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
    values[5] = f64::NAN;
    let mut flow = turning(&positions, 1.0);
    flow[7] = Vector3::new(f64::NAN, 0.0, 0.0);
    let style = PictureStyle::default();
    let grey_image = grey_picture(&camera, surface, &values, (0.0, 1.0), &style).unwrap();
    flow_picture(&camera, surface, &flow, 1.0, &style).unwrap();
    arrow_picture(&camera, surface, &values, (0.0, 1.0), &flow, 1.0, &style).unwrap();
    scalar_picture(&camera, surface, &values, (0.0, 1.0), &style).unwrap();
    // The rest of the sphere is still drawn.
    assert!(!is_background(&grey_image, 40, 30));
    // Framing ignores the non-finite points.
    let framed = Camera::framing(&positions, View::default(), 80, 60);
    assert!(framed.eye().iter().all(|x| x.is_finite()));
    let all_nan = vec![Vector3::repeat(f64::NAN); 3];
    let nan_surface = Surface {
        positions: &all_nan,
        faces: &[[0, 1, 2]],
    };
    let image = grey_picture(&framed, nan_surface, &[0.5; 3], (0.0, 1.0), &style).unwrap();
    assert!(image.pixels().all(|p| p.0 == [255; 3]));
}

#[test]
fn colormaps_and_labels() {
    assert_eq!(grey(0.25, 0.0, 1.0), [0.25; 3]);
    assert_eq!(grey(5.0, 0.0, 1.0), [1.0; 3]);
    assert_eq!(grey(-5.0, 0.0, 1.0), [0.0; 3]);
    assert_eq!(grey(3.0, 2.0, 2.0), [0.5; 3]);
    assert_eq!(grey(f64::NAN, 0.0, 1.0), [0.0; 3]);
    // Viridis ends: #440154 and #fde725.
    let low = viridis(0.0, 0.0, 10.0).map(|c| (c * 255.0).round());
    let high = viridis(10.0, 0.0, 10.0).map(|c| (c * 255.0).round());
    assert_eq!(low, [68.0, 1.0, 84.0]);
    assert_eq!(high, [253.0, 231.0, 37.0]);
    assert_eq!(viridis(f64::INFINITY, 0.0, 1.0), [0.0; 3]);
    assert_eq!(
        finite_range(&[3.0, f64::NAN, -1.0, 2.0, f64::INFINITY]),
        Some((-1.0, 3.0))
    );
    assert_eq!(finite_range(&[f64::NAN]), None);
    assert_eq!(format_value(0.123456), "0.123");
    assert_eq!(format_value(12.345), "12.3");
    assert_eq!(format_value(4.56e-5), "4.56e-5");
    assert_eq!(format_value(0.0), "0");
    for (x, text) in [
        (3.33333158493042, "3.33333"),
        (3.0, "3"),
        (-2.5, "-2.5"),
        (0.05, "0.05"),
        (9.9999996, "10"),
        (123456.7, "123457"),
        (2.0f32 as f64 / 3.0, "0.666667"),
        (0.00012345678, "0.000123457"),
        (1.5e-7, "1.5e-7"),
        (1234567890.0, "1.23457e9"),
        (-0.0, "0"),
        (f64::INFINITY, "inf"),
    ] {
        assert_eq!(format_number(x), text, "{x}");
    }
}

#[test]
fn chart_blocks_follow_rows_and_columns() {
    let colours: Vec<[f64; 3]> = (0..6).map(|k| [k as f64 / 5.0, 0.0, 0.0]).collect();
    let mut colours_with_nan = colours.clone();
    colours_with_nan[5] = [f64::NAN, 0.0, 0.0];
    let image = chart_picture(2, 3, &colours_with_nan, 4).unwrap();
    assert_eq!(image.dimensions(), (12, 8));
    // Vertex r·3 + c at block (c, r), row 0 on top.
    for (x, y, p) in image.enumerate_pixels() {
        let vertex = (y / 4) * 3 + x / 4;
        let expected = if vertex == 5 {
            0
        } else {
            (vertex as f64 / 5.0 * 255.0).round() as u8
        };
        assert_eq!(p.0, [expected, 0, 0], "({x}, {y})");
    }
}

#[test]
fn png_files_round_trip_and_are_written_atomically() {
    let directory = tempfile::tempdir().unwrap();
    let path = directory.path().join("chart.png");
    let image = chart_picture(
        2,
        2,
        &[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.5; 3]],
        3,
    )
    .unwrap();
    write_png(&path, &image).unwrap();
    let read = image::open(&path).unwrap().to_rgb8();
    assert_eq!(read, image);
    let leftovers: Vec<_> = std::fs::read_dir(directory.path()).unwrap().collect();
    assert_eq!(leftovers.len(), 1);
    let error = write_png(&directory.path().join("missing/dir/x.png"), &image).unwrap_err();
    assert!(error.to_string().contains("missing/dir/x.png"), "{error}");
}

/// Paths are drawn for the vertices arrows would get (one per screen cell), each ending in a
/// dot of the last colour; a path through a point hidden behind the surface loses that segment.
#[test]
fn paths_are_drawn_where_visible_from_the_arrow_cells() {
    use meshflow::render::glyphs::draw_paths;
    let (positions, faces) = sphere_at(Vector3::zeros());
    let camera = camera_from_front(4.0, 200, 200);
    let end = [1.0, 0.0, 0.0];
    let turn = nalgebra::Rotation3::from_axis_angle(&Vector3::z_axis(), 0.2);
    let paths: Vec<Vec<Vector3<f64>>> = positions.iter().map(|p| vec![*p, turn * p]).collect();
    let mut canvas = white_surface(&camera, &positions, &faces);
    let chosen = glyph_vertices(&canvas, &camera, &positions, &faces, 20.0).len();
    let drawn = draw_paths(
        &mut canvas,
        &camera,
        (&positions, &faces),
        &paths,
        20.0,
        2.0,
        |_| end,
    )
    .unwrap();
    assert!(
        chosen > 10 && drawn > chosen / 2 && drawn <= chosen,
        "{drawn} of {chosen}"
    );
    let image = canvas.finish();
    let red = image
        .pixels()
        .filter(|p| p[0] > 200 && p[1] < 60 && p[2] < 60)
        .count();
    assert!(red > 5 * drawn, "{red} red pixels for {drawn} paths");
    // Paths that end on the far side of the sphere draw no dot.
    let hidden: Vec<Vec<Vector3<f64>>> = positions.iter().map(|p| vec![*p, -p]).collect();
    let mut canvas = white_surface(&camera, &positions, &faces);
    let drawn = draw_paths(
        &mut canvas,
        &camera,
        (&positions, &faces),
        &hidden,
        20.0,
        2.0,
        |_| end,
    )
    .unwrap();
    assert_eq!(drawn, 0);
}
