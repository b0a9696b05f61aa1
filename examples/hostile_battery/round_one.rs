//! The first round's cases: bombs (tiny files declaring terabytes), files that name files
//! outside their directory, outputs over inputs, unbounded options, an edited manifest. Each
//! may end in exit 0 or a one-line error ([`Expect::Any`]).

use super::hostile_support;
use super::{Case, Expect};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// The cases: a name and the command line (without `meshflow`), with their files written
/// below `base`.
pub(super) fn cases(base: &Path, binary: &Path) -> Vec<Case> {
    std::fs::create_dir_all(base).unwrap();
    let files = Files::write(base, binary);
    let p = |path: &Path| path.to_str().unwrap().to_string();
    let out = |name: &str| p(&base.join(format!("out_{name}")));
    let mut cases: Vec<Case> = Vec::new();
    let mut case = |name: &str, args: &[&str]| cases.push(Case::new(name, args, Expect::Any));
    let (frames, volume, points) = (p(&files.frames), p(&files.volume), p(&files.points));
    // Files naming files elsewhere.
    for (label, gltf) in &files.linking_gltf {
        case(
            &format!("gltf uri {label}"),
            &["operators", &p(gltf), "--out", &out("gltf")],
        );
    }
    case(
        "obj mtllib /etc/passwd",
        &["solve", &p(&files.obj_mtllib), "--out", &out("mtl")],
    );
    case(
        "mtl map_Kd ../secret.png",
        &["solve", &p(&files.obj_map), "--out", &out("map")],
    );
    case(
        "png texture of 10^5 × 10^5",
        &["solve", &p(&files.obj_png_bomb), "--out", &out("png")],
    );
    // Bombs: tiny files declaring terabytes.
    case(
        "npy volume (10^12, 0, 4, 4)",
        &[
            "sample",
            &p(&files.npy_zero_axis),
            &frames,
            "--out",
            &out("a.npy"),
        ],
    );
    case(
        "npy points (10^12, 3)",
        &["surface", &p(&files.npy_huge), "--out", &out("pts")],
    );
    case(
        "npy positions (10^6, 10^6, 3)",
        &["solve", &p(&files.npy_sequence), "--out", &out("seq")],
    );
    case(
        "tiff 64 pages of 8192² on one strip",
        &[
            "sample",
            &p(&files.tiff_bomb),
            &frames,
            "--out",
            &out("t.npy"),
            "--voxel-size",
            "1,1,1",
        ],
    );
    case(
        "ply of 10^12 vertices",
        &["operators", &p(&files.ply_bomb), "--out", &out("ply")],
    );
    case(
        "glb declaring 4 GB",
        &["operators", &p(&files.glb_bomb), "--out", &out("glb")],
    );
    case(
        "vtu of 10^12 points",
        &["render", &p(&files.vtu_run), "--out", &out("vtu")],
    );
    case(
        "npy zero-length points (0, 3)",
        &["surface", &p(&files.empty_points), "--out", &out("e")],
    );
    case(
        "csv points × 1e100",
        &["surface", &p(&files.huge_points), "--out", &out("h")],
    );
    // Outputs over inputs.
    case(
        "sample --out VOLUME",
        &[
            "sample",
            &volume,
            &frames,
            "--out",
            &volume,
            "--voxel-size",
            "0.15,0.15,0.3",
            "--origin=-1.2,-1.2,-1.2",
        ],
    );
    case(
        "sample --out SEQ/frame_0.obj",
        &[
            "sample",
            &volume,
            &frames,
            "--out",
            &p(&files.frames.join("frame_0.obj")),
        ],
    );
    case(
        "match --out its input",
        &["match", &points, "--out", &p(&files.points.join("p0.npy"))],
    );
    case(
        "solve --out inside its input",
        &["solve", &frames, "--out", &p(&files.frames.join("out"))],
    );
    // Options whose cost has no bound.
    case(
        "sample --smooth 1e9",
        &[
            "sample",
            &volume,
            &frames,
            "--out",
            &out("s.npy"),
            "--smooth",
            "1e9",
        ],
    );
    case(
        "sample --smooth 1e4",
        &[
            "sample",
            &volume,
            &frames,
            "--out",
            &out("s.npy"),
            "--smooth",
            "1e4",
        ],
    );
    case(
        "sample --layers 10^9",
        &[
            "sample",
            &volume,
            &frames,
            "--out",
            &out("l.npy"),
            "--shell",
            "1,1",
            "--layers",
            "1000000000",
        ],
    );
    case(
        "match --max-distance nan",
        &[
            "match",
            &points,
            "--out",
            &out("m.npy"),
            "--max-distance",
            "nan",
        ],
    );
    case(
        "track --reference-vertices 10^8",
        &[
            "track",
            &frames,
            "--out",
            &out("tr"),
            "--reference-vertices",
            "100000000",
        ],
    );
    // An edited run.
    case(
        "advect of an edited manifest",
        &["advect", &p(&files.edited_run), "--out", &out("adv")],
    );
    cases
}

/// The files of the battery.
struct Files {
    frames: PathBuf,
    volume: PathBuf,
    points: PathBuf,
    linking_gltf: Vec<(String, PathBuf)>,
    obj_mtllib: PathBuf,
    obj_map: PathBuf,
    obj_png_bomb: PathBuf,
    npy_zero_axis: PathBuf,
    npy_huge: PathBuf,
    npy_sequence: PathBuf,
    tiff_bomb: PathBuf,
    ply_bomb: PathBuf,
    glb_bomb: PathBuf,
    vtu_run: PathBuf,
    empty_points: PathBuf,
    huge_points: PathBuf,
    edited_run: PathBuf,
}

impl Files {
    fn write(base: &Path, binary: &Path) -> Self {
        let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("meshes/rotating_sphere");
        let frames = base.join("frames");
        std::fs::create_dir(&frames).unwrap();
        for k in 0..3 {
            let name = format!("frame_{k}.obj");
            std::fs::copy(shipped.join(&name), frames.join(&name)).unwrap();
        }
        let volume = base.join("volume.npy");
        // Three frames of 8 × 16 × 16 voxels around the unit sphere (voxel size 0.15, origin −1.2).
        meshflow::format::write_npy(&volume, &[3, 8, 16, 16], &vec![0.5f32; 3 * 8 * 16 * 16])
            .unwrap();
        let points = base.join("points");
        std::fs::create_dir(&points).unwrap();
        for k in 0..2 {
            let values: Vec<f64> = (0..30)
                .map(|i| (i * 7 % 11) as f64 + 0.1 * k as f64)
                .collect();
            meshflow::format::write_npy(&points.join(format!("p{k}.npy")), &[10, 3], &values)
                .unwrap();
        }
        Self {
            linking_gltf: linking_gltf(base),
            obj_mtllib: textured_obj_frames(base, "objmtl", "mtllib /etc/passwd"),
            obj_map: {
                let dir = textured_obj_frames(base, "objmap", "mtllib skin.mtl");
                std::fs::write(base.join("secret.png"), b"secret").unwrap();
                std::fs::write(dir.join("skin.mtl"), "newmtl skin\nmap_Kd ../secret.png\n").unwrap();
                dir
            },
            obj_png_bomb: {
                let dir = textured_obj_frames(base, "objpng", "mtllib skin.mtl");
                std::fs::write(dir.join("skin.mtl"), "newmtl skin\nmap_Kd bomb.png\n").unwrap();
                std::fs::write(dir.join("bomb.png"), png_declaring(100_000, 100_000)).unwrap();
                dir
            },
            npy_zero_axis: write(base, "zero_axis.npy", npy_header("<f4", &[1_000_000_000_000, 0, 4, 4])),
            npy_huge: write(base, "huge.npy", npy_header("<f8", &[1_000_000_000_000, 3])),
            npy_sequence: {
                let dir = base.join("npyseq");
                std::fs::create_dir(&dir).unwrap();
                write(&dir, "positions.npy", npy_header("<f8", &[1_000_000, 1_000_000, 3]));
                meshflow::format::write_npy(&dir.join("faces.npy"), &[1, 3], &[0i64, 1, 2]).unwrap();
                dir
            },
            tiff_bomb: write(base, "bomb.tif", tiff_bomb(64, 8192)),
            ply_bomb: write(
                base,
                "bomb.ply",
                b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\n\
                  property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n\
                  end_header\n"
                    .to_vec(),
            ),
            glb_bomb: write(base, "bomb.glb", glb_declaring(4_000_000_000)),
            vtu_run: vtu_run(base),
            empty_points: write(base, "empty.npy", npy_header("<f8", &[0, 3])),
            huge_points: {
                let dir = base.join("hugepoints");
                std::fs::create_dir(&dir).unwrap();
                for k in 0..2 {
                    let rows: String = (0..20)
                        .map(|i| format!("{:e},{:e},{:e}\n", i as f64 * 1e100, (i * i % 7) as f64 * 1e100, (i as f64).sin() * (k + 1) as f64 * 1e100))
                        .collect();
                    std::fs::write(dir.join(format!("t{k}.csv")), format!("x,y,z\n{rows}")).unwrap();
                }
                dir
            },
            edited_run: edited_run(base, &frames, binary),
            frames,
            volume,
            points,
        }
    }
}

pub(super) fn write(dir: &Path, name: &str, bytes: Vec<u8>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// A version-1 NPY header for `descr` and `shape`, without data.
fn npy_header(descr: &str, shape: &[u64]) -> Vec<u8> {
    hostile_support::npy(descr, &hostile_support::shape_tuple(shape), &[])
}

/// `.gltf` files of one triangle whose buffer URI names something outside their directory.
fn linking_gltf(base: &Path) -> Vec<(String, PathBuf)> {
    let dir = base.join("gltf");
    std::fs::create_dir(&dir).unwrap();
    let uris = [
        "/etc/passwd",
        "../../../../etc/passwd",
        "%2e%2e/%2e%2e/%2e%2e/%2e%2e/etc/passwd",
        "/proc/self/environ",
        "/dev/zero",
        "file:///etc/passwd",
    ];
    uris.iter()
        .enumerate()
        .map(|(i, uri)| {
            let json = serde_json::json!({
                "asset": {"version": "2.0"},
                "buffers": [{"uri": uri, "byteLength": 42}],
                "bufferViews": [{"buffer": 0, "byteLength": 36}, {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
                "accessors": [
                    {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]},
                    {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}
                ],
                "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
                "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0
            });
            (uri.to_string(), write(&dir, &format!("m{i}.gltf"), json.to_string().into_bytes()))
        })
        .collect()
}

/// Two OBJ frames of a textured square in `base/name`, whose first line is `library`.
fn textured_obj_frames(base: &Path, name: &str, library: &str) -> PathBuf {
    let dir = base.join(name);
    std::fs::create_dir(&dir).unwrap();
    for k in 0..2 {
        let text = format!(
            "{library}\nv 0 0 {k}\nv 1 0 {k}\nv 1 1 {k}\nv 0 1 {k}\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
             usemtl skin\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
        );
        std::fs::write(dir.join(format!("f{k}.obj")), text).unwrap();
    }
    dir
}

/// A PNG whose header declares `width × height` RGB pixels, with almost no data.
fn png_declaring(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut chunk = |kind: &[u8], data: &[u8]| {
        bytes.extend((data.len() as u32).to_be_bytes());
        let mut crc = flate2::Crc::new();
        crc.update(kind);
        crc.update(data);
        bytes.extend(kind);
        bytes.extend(data);
        bytes.extend(crc.sum().to_be_bytes());
    };
    let mut header = Vec::new();
    header.extend(width.to_be_bytes());
    header.extend(height.to_be_bytes());
    header.extend([8, 2, 0, 0, 0]);
    chunk(b"IHDR", &header);
    chunk(b"IDAT", &deflate(&vec![0u8; 4096]));
    chunk(b"IEND", &[]);
    bytes
}

pub(super) fn deflate(data: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    encoder.write_all(data).unwrap();
    encoder.finish().unwrap()
}

/// A little-endian TIFF of `pages` pages of `side × side` 8-bit pixels, every page's one
/// deflate strip the same few kilobytes that inflate to the whole page.
fn tiff_bomb(pages: usize, side: u32) -> Vec<u8> {
    let strip = deflate(&vec![0u8; (side as usize) * (side as usize)]);
    let page = hostile_support::Page {
        compression: 8,
        strip_bytes: strip.len() as u32,
        ..hostile_support::Page::bytes(side, side)
    };
    hostile_support::tiff_bytes(&vec![page; pages], &strip)
}

/// A GLB whose JSON declares a buffer of `bytes` bytes in a BIN chunk that is not there.
fn glb_declaring(bytes: u64) -> Vec<u8> {
    let json = serde_json::json!({
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": bytes}],
        "bufferViews": [{"buffer": 0, "byteLength": bytes}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": bytes / 12, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 1]}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}], "scene": 0
    })
    .to_string();
    let mut json = json.into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend((12 + 8 + json.len() as u32 + 8).to_le_bytes());
    glb.extend((json.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json);
    glb.extend(u32::MAX.to_le_bytes());
    glb.extend(b"BIN\0");
    glb
}

/// A directory that looks like a run whose `flow.pvd` lists a VTU declaring 10¹² points.
fn vtu_run(base: &Path) -> PathBuf {
    let dir = base.join("vturun");
    std::fs::create_dir(&dir).unwrap();
    std::fs::write(
        dir.join("flow.pvd"),
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n<Collection>\n\
         <DataSet timestep=\"0\" file=\"flow_0000.vtu\"/>\n</Collection>\n</VTKFile>\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("flow_0000.vtu"),
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\">\n<UnstructuredGrid>\n\
         <Piece NumberOfPoints=\"1000000000000\" NumberOfCells=\"1000000000000\">\n<Points>\n\
         <DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">0 0 0</DataArray>\n\
         </Points>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n",
    )
    .unwrap();
    dir
}

/// A run of `frames` whose manifest was edited to name `/etc` as the solve's input.
fn edited_run(base: &Path, frames: &Path, binary: &Path) -> PathBuf {
    let run = base.join("run");
    let solved = Command::new(binary)
        .args([
            "solve",
            frames.to_str().unwrap(),
            "--out",
            run.to_str().unwrap(),
        ])
        .args(["--format", "npy", "--quiet"])
        .stdout(Stdio::null())
        .status()
        .expect("the binary starts");
    assert!(solved.success(), "the run to edit");
    let manifest = run.join("meshflow_run.json");
    let text = std::fs::read_to_string(&manifest).unwrap();
    let mut json: serde_json::Value = serde_json::from_str(&text).unwrap();
    json["commands"][0][2] = serde_json::Value::from("/etc");
    std::fs::write(&manifest, json.to_string()).unwrap();
    run
}
