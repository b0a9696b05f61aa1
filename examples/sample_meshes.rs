//! Regenerates the small meshes shipped in `meshes/`:
//! `cargo run --release --example sample_meshes`.

use meshflow::io::write_obj;
use meshflow::shapes::{grid, icosphere, torus};
use std::path::Path;

fn main() -> Result<(), meshflow::Error> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes");
    let samples = [
        ("icosphere.obj", icosphere(3)),
        ("torus.obj", torus(2.0, 0.8, 32, 16)),
        ("patch.obj", grid(12, 8, 1.5, 1.0)),
    ];
    for (name, surface) in samples {
        write_obj(&dir.join(name), &surface.positions, &surface.faces, None)?;
        println!(
            "{name}: {} vertices, {} faces",
            surface.positions.len(),
            surface.faces.len()
        );
    }
    Ok(())
}
