//! Pictures of a turning sphere (grey values, flow colours, arrows, speed) and a parameter
//! chart, written to a directory (default `out/render_demo`), and the time to draw a
//! 100k-triangle torus at 800×600. `cargo run --release --example render_demo [DIR]`
use meshflow::render::colormap::finite_range;
use meshflow::render::{
    arrow_picture, chart_picture, flow_picture, grey_picture, scalar_picture, write_png, Camera,
    PictureStyle, Surface, View,
};
use meshflow::shapes::{icosphere, torus};
use meshflow::synth::texture;
use nalgebra::Vector3;
use std::path::PathBuf;
use std::time::Instant;

fn main() -> Result<(), meshflow::Error> {
    let directory = PathBuf::from(std::env::args().nth(1).unwrap_or("out/render_demo".into()));
    std::fs::create_dir_all(&directory).map_err(|e| meshflow::format::IoError::File {
        path: directory.clone(),
        source: e,
    })?;
    let sphere = icosphere(5);
    let surface = Surface {
        positions: &sphere.positions,
        faces: &sphere.faces,
    };
    let grey: Vec<f64> = sphere.positions.iter().map(texture).collect();
    let flow: Vec<Vector3<f64>> = sphere
        .positions
        .iter()
        .map(|p| 0.5 * Vector3::z().cross(p))
        .collect();
    let speed: Vec<f64> = flow.iter().map(|u| u.norm()).collect();
    let range = finite_range(&grey).expect("finite grey values");
    let camera = Camera::framing(&sphere.positions, View::default(), 800, 600);
    let style = |label: &str| PictureStyle {
        label: Some(label.into()),
        ..PictureStyle::default()
    };
    let pictures = [
        (
            "grey.png",
            grey_picture(
                &camera,
                surface,
                &grey,
                range,
                &style("grey values  t = 0.00"),
            )?,
        ),
        (
            "flow.png",
            flow_picture(&camera, surface, &flow, 0.5, &style("slab 0  t = 0.00"))?,
        ),
        (
            "arrows.png",
            arrow_picture(
                &camera,
                surface,
                &grey,
                range,
                &flow,
                0.5,
                &style("slab 0  t = 0.00"),
            )?,
        ),
        (
            "speed.png",
            scalar_picture(&camera, surface, &speed, (0.0, 0.5), &style("|u|"))?,
        ),
    ];
    for (name, image) in &pictures {
        write_png(&directory.join(name), image)?;
    }
    let (rows, cols) = (20, 30);
    let chart: Vec<[f64; 3]> = (0..rows * cols)
        .map(|k| {
            [
                (k / cols) as f64 / rows as f64,
                (k % cols) as f64 / cols as f64,
                0.5,
            ]
        })
        .collect();
    write_png(
        &directory.join("chart.png"),
        &chart_picture(rows, cols, &chart, 8)?,
    )?;

    let ring = torus(1.0, 0.4, 250, 200);
    let ring_grey: Vec<f64> = ring.positions.iter().map(texture).collect();
    let ring_camera = Camera::framing(&ring.positions, View::default(), 800, 600);
    let ring_surface = Surface {
        positions: &ring.positions,
        faces: &ring.faces,
    };
    for _ in 0..3 {
        let start = Instant::now();
        let image = grey_picture(
            &ring_camera,
            ring_surface,
            &ring_grey,
            (0.0, 1.0),
            &PictureStyle::default(),
        )?;
        println!(
            "{} triangles, 800×600, supersample 3: {:.3} s",
            ring.faces.len(),
            start.elapsed().as_secs_f64()
        );
        write_png(&directory.join("torus.png"), &image)?;
    }
    println!("wrote {}", directory.display());
    Ok(())
}
