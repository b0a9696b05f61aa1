//! PLY: bit-exact round trips, hand-made files in every encoding, one test per error, and a
//! no-panic loop over truncated and corrupted files.

use meshflow::io::ply::{read_ply, write_ply, PlyEncoding, PlyMesh};
use meshflow::io::IoError;
use meshflow::shapes::icosphere;
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// A deterministic xorshift64 generator, so failures reproduce.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// Uniform in [-1, 1).
    fn signed(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn write_file(dir: &Path, name: &str, contents: impl AsRef<[u8]>) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

fn bits(values: impl IntoIterator<Item = f64>) -> Vec<u64> {
    values.into_iter().map(f64::to_bits).collect()
}

/// A sphere with awkward numbers everywhere: jittered positions, colours outside [0, 1],
/// properties with signed zero, subnormals and extreme exponents.
struct Sample {
    positions: Vec<Vector3<f64>>,
    faces: Vec<[u32; 3]>,
    colors: Vec<[f64; 3]>,
    intensity: Vec<f64>,
    quality: Vec<f64>,
}

fn sample(level: u32) -> Sample {
    let sphere = icosphere(level);
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let positions: Vec<Vector3<f64>> = sphere
        .positions
        .iter()
        .map(|p| p * (1.0 + 1e-3 * rng.signed()) + Vector3::repeat(1e-17))
        .collect();
    let specials = [-0.0, 5e-324, 1e300, -1e-300, f64::MAX, f64::MIN_POSITIVE];
    let n = positions.len();
    Sample {
        colors: (0..n)
            .map(|_| [rng.signed(), rng.signed() / 3.0, 1.7])
            .collect(),
        intensity: (0..n).map(|i| specials[i % specials.len()]).collect(),
        quality: (0..n).map(|_| rng.signed() * 1e-8).collect(),
        faces: sphere.faces,
        positions,
    }
}

fn round_trip(encoding: PlyEncoding) {
    let dir = tempfile::tempdir().unwrap();
    let s = sample(2);
    let path = dir.path().join("sphere.ply");
    let properties: [(&str, &[f64]); 2] = [("intensity", &s.intensity), ("quality", &s.quality)];
    write_ply(
        &path,
        &s.positions,
        &s.faces,
        Some(&s.colors),
        &properties,
        encoding,
    )
    .unwrap();
    let back = read_ply(&path).unwrap();
    assert_eq!(
        bits(back.positions.iter().flat_map(|p| [p.x, p.y, p.z])),
        bits(s.positions.iter().flat_map(|p| [p.x, p.y, p.z]))
    );
    assert_eq!(back.faces, s.faces);
    assert_eq!(
        bits(back.colors.unwrap().into_iter().flatten()),
        bits(s.colors.iter().copied().flatten())
    );
    let names: Vec<&str> = back.properties.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["intensity", "quality"]);
    assert_eq!(
        bits(back.properties[0].1.clone()),
        bits(s.intensity.clone())
    );
    assert_eq!(bits(back.properties[1].1.clone()), bits(s.quality.clone()));
}

#[test]
fn ascii_round_trip_is_bit_exact() {
    round_trip(PlyEncoding::Ascii);
}

#[test]
fn binary_round_trip_is_bit_exact() {
    round_trip(PlyEncoding::BinaryLittleEndian);
}

#[test]
fn mesh_without_colours_or_properties_round_trips() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = icosphere(0);
    for encoding in [PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian] {
        let path = dir.path().join("plain.ply");
        write_ply(&path, &sphere.positions, &sphere.faces, None, &[], encoding).unwrap();
        let expected = PlyMesh {
            positions: sphere.positions.clone(),
            faces: sphere.faces.clone(),
            colors: None,
            properties: vec![],
        };
        assert_eq!(read_ply(&path).unwrap(), expected);
    }
}

#[test]
fn ascii_file_with_uchar_colours_a_quad_an_edge_element_and_extra_face_properties() {
    let dir = tempfile::tempdir().unwrap();
    let text = "ply\r\n\
        format ascii 1.0\n\
        comment a unit square and a triangle beside it\n\
        obj_info made by hand\n\
        element vertex 5\n\
        property float x\nproperty float y\nproperty float z\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n\
        property float intensity\n\
        property list uchar float texcoord\n\
        property short label\n\
        element edge 2\n\
        property int vertex1\nproperty int vertex2\nproperty list uchar uchar tags\n\
        element face 2\n\
        property uchar flags\n\
        property list uchar int vertex_indices\n\
        property list uchar float texcoord\n\
        end_header\n\
        0 0 0   255 0 51 255   0.25 2 0 0   -7\n\
        1 0 0   0 255 0 128    0.5  0       300\n\
        1 1 0   0 0 255 0      -1.5 1 0.5   0\n\
        0 1 0   102 102 102 1  2    0       1\n\
        2 0.5 0 0 0 0 0        1e3  3 1 2 3 2\n\
        0 1 3 7 8 9\n\
        1 2 0\n\
        4   4 3 0 1 2   0\n\
        0   3 1 4 2     2 0.5 0.5\n\
        trailing garbage is ignored\n";
    let mesh = read_ply(&write_file(dir.path(), "quad.ply", text)).unwrap();
    assert_eq!(mesh.positions.len(), 5);
    assert_eq!(mesh.positions[4], Vector3::new(2.0, 0.5, 0.0));
    assert_eq!(mesh.faces, vec![[3, 0, 1], [3, 1, 2], [1, 4, 2]]);
    let colors = mesh.colors.unwrap();
    assert_eq!(colors[0], [1.0, 0.0, 51.0 / 255.0]);
    assert_eq!(colors[3], [102.0 / 255.0; 3]);
    assert_eq!(
        mesh.properties,
        vec![
            ("intensity".to_string(), vec![0.25, 0.5, -1.5, 2.0, 1000.0]),
            ("label".to_string(), vec![-7.0, 300.0, 0.0, 1.0, 2.0]),
        ]
    );
}

/// Header lines, then the body.
fn ply_bytes(header: &str, body: &[u8]) -> Vec<u8> {
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend_from_slice(body);
    bytes
}

/// A tetrahedron in big-endian binary: float positions, ushort colours, an `edge` element with
/// a list between vertices and faces, faces with int indices and a property on each side.
fn big_endian_tetrahedron() -> Vec<u8> {
    let header = "ply\nformat binary_big_endian 1.0\n\
        element vertex 4\n\
        property float x\nproperty float y\nproperty float z\n\
        property ushort red\nproperty ushort green\nproperty ushort blue\n\
        element edge 2\n\
        property list uchar int vertices\nproperty double weight\n\
        element face 4\n\
        property uchar flags\n\
        property list ushort int vertex_indices\n\
        property float area\n\
        end_header\n";
    let mut body = Vec::new();
    let vertices = [
        ([0.5f32, -1.25, 3.0], [65535u16, 0, 32768]),
        ([1.0, 0.0, 0.0], [0, 65535, 0]),
        ([0.0, 1.0, 0.0], [0, 0, 65535]),
        ([0.0, 0.0, -0.0], [13107, 13107, 13107]),
    ];
    for (position, color) in vertices {
        position.iter().for_each(|v| body.extend(v.to_be_bytes()));
        color.iter().for_each(|v| body.extend(v.to_be_bytes()));
    }
    for edge in [&[0i32, 1][..], &[1, 2, 3]] {
        body.push(edge.len() as u8);
        edge.iter().for_each(|v| body.extend(v.to_be_bytes()));
        body.extend(0.5f64.to_be_bytes());
    }
    for face in [[0i32, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
        body.push(0xff);
        body.extend(3u16.to_be_bytes());
        face.iter().for_each(|v| body.extend(v.to_be_bytes()));
        body.extend(1.5f32.to_be_bytes());
    }
    ply_bytes(header, &body)
}

#[test]
fn big_endian_binary_with_float_positions_ushort_colours_and_int_indices() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = read_ply(&write_file(dir.path(), "be.ply", big_endian_tetrahedron())).unwrap();
    assert_eq!(
        bits(mesh.positions.iter().flat_map(|p| [p.x, p.y, p.z])),
        bits([0.5, -1.25, 3.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -0.0])
    );
    assert_eq!(mesh.faces, vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]);
    let colors = mesh.colors.unwrap();
    assert_eq!(colors[0], [1.0, 0.0, 32768.0 / 65535.0]);
    assert_eq!(colors[3], [0.2; 3]); // 13107 / 65535 = 1/5, rounded the same way
    assert!(mesh.properties.is_empty());
}

#[test]
fn little_endian_binary_reads_every_scalar_type_under_both_names() {
    let dir = tempfile::tempdir().unwrap();
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
        property int16 x\nproperty uint32 y\nproperty float64 z\n\
        property char a\nproperty uchar b\nproperty short c\nproperty ushort d\n\
        property int e\nproperty uint f\nproperty float g\nproperty double h\n\
        property int8 a8\nproperty uint8 b8\nproperty uint16 d16\nproperty float32 g32\n\
        element face 1\nproperty list int8 uint32 vertex_index\nend_header\n";
    let mut body = Vec::new();
    for k in 0..3u32 {
        body.extend((-(k as i16)).to_le_bytes());
        body.extend((k * 1000).to_le_bytes());
        body.extend((k as f64 / 3.0).to_le_bytes());
        body.extend((i8::MIN + k as i8).to_le_bytes());
        body.extend((u8::MAX - k as u8).to_le_bytes());
        body.extend(i16::MIN.to_le_bytes());
        body.extend(u16::MAX.to_le_bytes());
        body.extend(i32::MIN.to_le_bytes());
        body.extend(u32::MAX.to_le_bytes());
        body.extend(0.1f32.to_le_bytes());
        body.extend(0.1f64.to_le_bytes());
        body.extend((-1i8).to_le_bytes());
        body.extend(7u8.to_le_bytes());
        body.extend(40000u16.to_le_bytes());
        body.extend((-2.5f32).to_le_bytes());
    }
    body.extend(3i8.to_le_bytes());
    [2u32, 0, 1]
        .iter()
        .for_each(|v| body.extend(v.to_le_bytes()));
    let mesh = read_ply(&write_file(dir.path(), "le.ply", ply_bytes(header, &body))).unwrap();
    assert_eq!(mesh.positions[2], Vector3::new(-2.0, 2000.0, 2.0 / 3.0));
    assert_eq!(mesh.faces, vec![[2, 0, 1]]);
    assert!(mesh.colors.is_none());
    let column = |name: &str| -> Vec<f64> {
        let found = mesh.properties.iter().find(|(n, _)| n == name);
        found.unwrap().1.clone()
    };
    assert_eq!(column("a"), [-128.0, -127.0, -126.0]);
    assert_eq!(column("b"), [255.0, 254.0, 253.0]);
    assert_eq!(column("c"), [-32768.0; 3]);
    assert_eq!(column("d"), [65535.0; 3]);
    assert_eq!(column("e"), [-2147483648.0; 3]);
    assert_eq!(column("f"), [4294967295.0; 3]);
    assert_eq!(column("g"), [f64::from(0.1f32); 3]);
    assert_eq!(column("h"), [0.1; 3]);
    assert_eq!(column("a8"), [-1.0; 3]);
    assert_eq!(column("b8"), [7.0; 3]);
    assert_eq!(column("d16"), [40000.0; 3]);
    assert_eq!(column("g32"), [-2.5; 3]);
    assert_eq!(mesh.properties.len(), 12);
}

/// The triangles of the strips `[0 1 2 3 4 | 5 6 7 7 8 9]` (`|` = −1), by hand: alternating
/// orientation from each start, the two with vertex 7 twice skipped.
const STRIP_TRIANGLES: [[u32; 3]; 5] = [[0, 1, 2], [2, 1, 3], [2, 3, 4], [5, 6, 7], [8, 7, 9]];

#[test]
fn triangle_strips_ascii_restart_alternate_and_skip_turns() {
    let dir = tempfile::tempdir().unwrap();
    // The strips come before the face element in the file; faces are listed first.
    let header = "ply\nformat ascii 1.0\nelement vertex 10\n\
        property float x\nproperty float y\nproperty float z\n\
        element tristrips 1\nproperty list int int vertex_indices\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let vertices: String = (0..10).map(|i| format!("{i} {} 0\n", i % 2)).collect();
    let body = format!("{vertices}12 0 1 2 3 4 -1 5 6 7 7 8 9\n3 0 9 5\n");
    let mesh = read_ply(&write_file(
        dir.path(),
        "strips.ply",
        ply_bytes(header, body.as_bytes()),
    ))
    .unwrap();
    let mut expected = vec![[0, 9, 5]];
    expected.extend(STRIP_TRIANGLES);
    assert_eq!(mesh.faces, expected);
    assert_eq!(mesh.positions.len(), 10);

    // Without a face element, strips alone make the mesh; a bad index names the strip.
    let header = header.replace(
        "element face 1\nproperty list uchar int vertex_indices\n",
        "",
    );
    let body = format!("{vertices}12 0 1 2 3 4 -1 5 6 7 7 8 9\n");
    let mesh = read_ply(&write_file(
        dir.path(),
        "strips.ply",
        ply_bytes(&header, body.as_bytes()),
    ))
    .unwrap();
    assert_eq!(mesh.faces, STRIP_TRIANGLES);
    let body = format!("{vertices}4 0 1 -2 3\n");
    let text = message(ply_error(ply_bytes(&header, body.as_bytes())), Some(20));
    assert!(
        text.contains("tristrips 0: negative vertex index -2"),
        "{text}"
    );
}

#[test]
fn triangle_strips_in_binary_span_records() {
    let dir = tempfile::tempdir().unwrap();
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 10\n\
        property float x\nproperty float y\nproperty float z\n\
        element tristrips 2\nproperty list int int vertex_indices\nend_header\n";
    let mut body = Vec::new();
    for i in 0..10 {
        [i as f32, (i % 2) as f32, 0.0]
            .iter()
            .for_each(|v| body.extend(v.to_le_bytes()));
    }
    // Two records: the second strip in its own record (each record starts a strip).
    for strip in [&[0i32, 1, 2, 3, 4][..], &[5, 6, 7, 7, 8, 9]] {
        body.extend((strip.len() as i32).to_le_bytes());
        strip.iter().for_each(|v| body.extend(v.to_le_bytes()));
    }
    let mesh = read_ply(&write_file(
        dir.path(),
        "strips.ply",
        ply_bytes(header, &body),
    ))
    .unwrap();
    assert_eq!(mesh.faces, STRIP_TRIANGLES);
}

// ---------------------------------------------------------------------------------------------
// Errors

fn ply_error(bytes: impl AsRef<[u8]>) -> IoError {
    let dir = tempfile::tempdir().unwrap();
    read_ply(&write_file(dir.path(), "bad.ply", bytes)).unwrap_err()
}

/// The error's message, asserting that it names the file and, when given, the line.
fn message(error: IoError, line: Option<usize>) -> String {
    let text = error.to_string();
    assert!(text.contains("bad.ply"), "{text}");
    match (&error, line) {
        (IoError::Parse { line: found, .. }, Some(expected)) => {
            assert_eq!(*found, expected, "{text}")
        }
        (IoError::Format { .. }, None) => {}
        _ => panic!("unexpected error kind or line: {error:?}"),
    }
    text
}

const TRIANGLE_HEADER: &str = "ply\nformat ascii 1.0\nelement vertex 3\n\
    property double x\nproperty double y\nproperty double z\n\
    element face 1\nproperty list uchar int vertex_indices\nend_header\n";

fn ascii_triangle(body: &str) -> String {
    format!("{TRIANGLE_HEADER}{body}")
}

#[test]
fn error_not_a_ply_file() {
    let text = message(ply_error("solid cube\nfacet normal 0 0 1\n"), None);
    assert!(text.contains("not a PLY file"), "{text}");
    let text = message(ply_error(""), None);
    assert!(text.contains("end_header"), "{text}");
}

#[test]
fn error_unknown_format_and_version() {
    let text = message(
        ply_error("ply\nformat binary_middle_endian 1.0\nend_header\n"),
        Some(2),
    );
    assert!(
        text.contains("unknown format 'binary_middle_endian'"),
        "{text}"
    );
    let text = message(ply_error("ply\nformat ascii 2.0\nend_header\n"), Some(2));
    assert!(text.contains("version '2.0'"), "{text}");
}

#[test]
fn error_unsupported_type() {
    let file = TRIANGLE_HEADER.replace("double y", "int64 y");
    let text = message(ply_error(file), Some(5));
    assert!(text.contains("unsupported property type 'int64'"), "{text}");
    let file = TRIANGLE_HEADER.replace("list uchar int", "list float int");
    let text = message(ply_error(file), Some(8));
    assert!(text.contains("integer type, not 'float'"), "{text}");
}

#[test]
fn error_missing_coordinate() {
    let file = TRIANGLE_HEADER.replace("property double z\n", "property double w\n");
    let text = message(ply_error(file), None);
    assert!(text.contains("no scalar property 'z'"), "{text}");
}

#[test]
fn error_point_cloud_without_faces() {
    let cloud = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
        property float z\nend_header\n0 0 0\n1 1 1\n";
    let text = message(ply_error(cloud), None);
    assert!(text.contains("no faces"), "{text}");
    let empty = ascii_triangle("0 0 0\n1 0 0\n0 1 0\n").replace("face 1", "face 0");
    let text = message(ply_error(empty), None);
    assert!(text.contains("no faces"), "{text}");
}

#[test]
fn error_face_without_vertex_indices() {
    let file = TRIANGLE_HEADER.replace("vertex_indices", "corners");
    let text = message(ply_error(file), None);
    assert!(text.contains("no 'vertex_indices'"), "{text}");
    let file = TRIANGLE_HEADER.replace("list uchar int vertex_indices", "int vertex_indices");
    let text = message(ply_error(file), None);
    assert!(text.contains("must be a list"), "{text}");
}

#[test]
fn error_index_out_of_range_negative_or_too_few() {
    let vertices = "0 0 0\n1 0 0\n0 1 0\n";
    let text = message(
        ply_error(ascii_triangle(&format!("{vertices}3 0 1 3\n"))),
        Some(13),
    );
    assert!(
        text.contains("face 0: vertex index 3 is out of range (the file has 3 vertices)"),
        "{text}"
    );
    let text = message(
        ply_error(ascii_triangle(&format!("{vertices}3 0 -1 2\n"))),
        Some(13),
    );
    assert!(text.contains("face 0: negative vertex index -1"), "{text}");
    let text = message(
        ply_error(ascii_triangle(&format!("{vertices}2 0 1\n"))),
        Some(13),
    );
    assert!(
        text.contains("face 0: 2 vertex indices; a face needs at least 3"),
        "{text}"
    );
}

#[test]
fn error_index_out_of_range_in_binary_names_the_face() {
    let mut file = big_endian_tetrahedron();
    // The last index of the last face: 3 → 4.
    let at = file.len() - 4 - 1;
    file[at] = 4;
    let text = message(ply_error(file), None);
    assert!(
        text.contains("face 3: vertex index 4 is out of range"),
        "{text}"
    );
}

#[test]
fn error_truncated_data() {
    let file = big_endian_tetrahedron();
    // Cut inside the third vertex (each vertex record is 3·4 + 3·2 = 18 bytes).
    let body_start = file.windows(11).position(|w| w == b"end_header\n").unwrap() + 11;
    let text = message(ply_error(&file[..body_start + 2 * 18 + 5]), None);
    assert!(text.contains("truncated"), "{text}");
    assert!(text.contains("'vertex'"), "{text}");
    // Cut inside the last face: enough bytes for the up-front check, not for the record.
    let text = message(ply_error(&file[..file.len() - 3]), None);
    assert!(
        text.contains("truncated file: the data ends in face 3 (the header declares 4)"),
        "{text}"
    );
    let text = message(
        ply_error(ascii_triangle("0 0 0\n1 0 0\n0 1 0\n3 0 1")),
        None,
    );
    assert!(text.contains("the data ends in face 0"), "{text}");
}

#[test]
fn error_huge_count_in_a_tiny_file_fails_before_allocating() {
    let file = ascii_triangle("0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
        .replace("vertex 3", "vertex 1000000000000");
    let text = message(ply_error(file), None);
    assert!(
        text.contains("truncated file: the header declares 1000000000000 'vertex' records"),
        "{text}"
    );
    let header = "ply\nformat binary_little_endian 1.0\nelement vertex 3\n\
        property double x\nproperty double y\nproperty double z\n\
        element material 18446744073709551615\nproperty double shine\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    let text = message(ply_error(ply_bytes(header, &[0; 80])), None);
    assert!(
        text.contains("'material' records, which need more than 2^64 bytes"),
        "{text}"
    );
}

#[test]
fn error_ascii_token_not_a_number_names_the_line() {
    let text = message(
        ply_error(ascii_triangle("0 0 0\n1 zero 0\n0 1 0\n3 0 1 2\n")),
        Some(11),
    );
    assert!(
        text.contains("'zero' is not a valid double (property 'y' of vertex 1)"),
        "{text}"
    );
    let text = message(
        ply_error(ascii_triangle("0 0 0\n1 0 0\n0 1 0\n300 0 1 2\n")),
        Some(13),
    );
    assert!(text.contains("'300' is not a valid uchar"), "{text}");
}

#[test]
fn error_header_structure() {
    let text = message(
        ply_error("ply\nformat ascii 1.0\nproperty float x\nend_header\n"),
        Some(3),
    );
    assert!(text.contains("property before any element"), "{text}");
    let text = message(
        ply_error("ply\nformat ascii 1.0\nelemnt vertex 3\n"),
        Some(3),
    );
    assert!(text.contains("unknown header keyword 'elemnt'"), "{text}");
    let text = message(ply_error("ply\nelement vertex 3\nend_header\n"), None);
    assert!(text.contains("no 'format' line"), "{text}");
    let text = message(
        ply_error(TRIANGLE_HEADER.replace("double y", "double x")),
        Some(5),
    );
    assert!(text.contains("property 'x' declared twice"), "{text}");
}

// ---------------------------------------------------------------------------------------------
// Robustness

/// Replaces the contents of `path` in place: far faster than `fs::write` on ext4, which flushes
/// a file that is truncated to zero and rewritten.
fn overwrite(path: &Path, bytes: &[u8]) {
    use std::io::Write;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(false)
        .open(path)
        .unwrap();
    file.write_all(bytes).unwrap();
    file.set_len(bytes.len() as u64).unwrap();
}

/// Reads `bytes`; a mesh that comes back must be consistent.
fn read_checked(path: &Path, bytes: &[u8]) -> Result<PlyMesh, IoError> {
    overwrite(path, bytes);
    let result = read_ply(path);
    if let Ok(mesh) = &result {
        let n = mesh.positions.len();
        assert!(mesh.faces.iter().flatten().all(|&v| (v as usize) < n));
        assert!(mesh.colors.as_ref().is_none_or(|c| c.len() == n));
        assert!(mesh.properties.iter().all(|(_, values)| values.len() == n));
    }
    result
}

#[test]
fn truncated_and_corrupted_files_give_errors_not_panics() {
    let dir = tempfile::tempdir().unwrap();
    let s = sample(0);
    let mut files = vec![];
    for (encoding, name) in [
        (PlyEncoding::Ascii, "a.ply"),
        (PlyEncoding::BinaryLittleEndian, "b.ply"),
    ] {
        let path = dir.path().join(name);
        let properties: [(&str, &[f64]); 1] = [("intensity", &s.intensity)];
        write_ply(
            &path,
            &s.positions,
            &s.faces,
            Some(&s.colors),
            &properties,
            encoding,
        )
        .unwrap();
        files.push((encoding, std::fs::read(&path).unwrap()));
    }
    let path = dir.path().join("mutated.ply");
    let mut rng = Rng(42);
    let mut outcomes = [0usize; 2];
    for (encoding, valid) in &files {
        assert!(read_checked(&path, valid).is_ok());
        for length in (0..valid.len()).step_by(3) {
            let result = read_checked(&path, &valid[..length]);
            // Every binary byte counts, so any cut is an error; an ASCII cut may land between
            // a number's digits, so only the absence of panics is checked there.
            if *encoding == PlyEncoding::BinaryLittleEndian {
                assert!(
                    result.is_err(),
                    "cut at {length} of {} was accepted",
                    valid.len()
                );
            }
        }
        for _ in 0..1500 {
            let mut bytes = valid.clone();
            for _ in 0..1 + rng.below(3) {
                let at = rng.below(bytes.len());
                bytes[at] ^= 1 << rng.below(8);
            }
            outcomes[read_checked(&path, &bytes).is_ok() as usize] += 1;
        }
    }
    let be = big_endian_tetrahedron();
    for length in 0..be.len() {
        assert!(read_checked(&path, &be[..length]).is_err());
    }
    // Both outcomes must occur, or the mutations test nothing.
    assert!(outcomes[0] > 100 && outcomes[1] > 100, "{outcomes:?}");
}

// ---------------------------------------------------------------------------------------------
// Writer input checks

#[test]
fn writer_rejects_inconsistent_input() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.ply");
    let sphere = icosphere(0);
    let n = sphere.positions.len();
    let write = |colors: Option<&[[f64; 3]]>, properties: &[(&str, &[f64])], faces: &[[u32; 3]]| {
        let error = write_ply(
            &path,
            &sphere.positions,
            faces,
            colors,
            properties,
            PlyEncoding::Ascii,
        )
        .unwrap_err();
        assert!(!path.exists());
        error.to_string()
    };
    let short = vec![0.0; n - 1];
    let full = vec![0.0; n];
    assert!(
        write(Some(&[[0.0; 3]; 2][..]), &[], &sphere.faces).contains("2 colours for 12 vertices")
    );
    assert!(write(None, &[("q", &short[..])], &sphere.faces).contains("'q' has 11 values"));
    assert!(write(None, &[("alpha", &full[..])], &sphere.faces).contains("reserved"));
    assert!(write(None, &[("q", &full[..]), ("q", &full[..])], &sphere.faces).contains("twice"));
    assert!(write(None, &[("a b", &full[..])], &sphere.faces).contains("without spaces"));
    assert!(write(None, &[], &[[0, 1, 12]]).contains("face 0 refers to vertex 12"));
}
