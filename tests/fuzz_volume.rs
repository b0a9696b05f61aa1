//! Fuzzing the volume and point readers with mutated files: valid small TIFF stacks, NPY
//! volumes, CSV point files and OME-Zarr images (v2, v3, sharded; every codec chain, written by
//! `zarrs`) with bytes flipped, cut short, or header fields (TIFF widths, heights, strip
//! offsets and counts, next-page pointers; NPY shapes; shard index entries, blosc and zstd
//! headers) set to extremes. Every reader must return `Ok` or `Err`, never panic, and stay
//! within the memory limit: a counting global allocator measures each case's peak on its
//! thread (the Zarr reader's threads run on the case's own, in a pool of one).
//!
//! `MESHFLOW_FUZZ_CASES` sets the cases per reader (default 3,000).

mod hostile_support;

use hostile_support::{npy_bytes, small_tiff, zarr};
use meshflow::surface::read_points;
use meshflow::volume::{count_volume_frames, read_volumes, VolumeOptions};
use proptest::prelude::*;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::path::Path;

/// The memory limit every test here sets.
const LIMIT: u64 = 64 << 20;
/// What a case may take beyond the limit: buffered readers, messages, the test's own data.
const MARGIN: i64 = 8 << 20;

thread_local! {
    static CURRENT: Cell<i64> = const { Cell::new(0) };
    static PEAK: Cell<i64> = const { Cell::new(0) };
}

/// `System`, counting the bytes each thread holds and their peak.
struct Counting;

fn count(delta: i64) {
    // `try_with`: a thread's locals may be gone while it exits.
    let _ = CURRENT.try_with(|current| {
        let now = current.get() + delta;
        current.set(now);
        let _ = PEAK.try_with(|peak| peak.set(peak.get().max(now)));
    });
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if !p.is_null() {
            count(layout.size() as i64);
        }
        p
    }

    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        System.dealloc(p, layout);
        count(-(layout.size() as i64));
    }

    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = System.realloc(p, layout, size);
        if !q.is_null() {
            count(size as i64 - layout.size() as i64);
        }
        q
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// The bytes `run` allocated at its peak beyond what the thread held before.
fn peak_of(run: impl FnOnce()) -> i64 {
    let base = CURRENT.with(Cell::get);
    PEAK.with(|peak| peak.set(base));
    run();
    PEAK.with(Cell::get) - base
}

fn cases() -> u32 {
    std::env::var("MESHFLOW_FUZZ_CASES")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(3000)
}

/// One change to a file.
#[derive(Clone, Debug)]
enum Mutation {
    /// XOR a byte.
    Flip(usize, u8),
    Truncate(usize),
    /// Set the 4 bytes at (a position modulo the length) to a value.
    SetU32(usize, u32),
}

fn extreme_u32() -> impl Strategy<Value = u32> {
    prop_oneof![
        Just(0u32),
        Just(1),
        Just(2),
        Just(8),
        Just(0xffff),
        Just(0x1_0000),
        Just(8192),
        Just(1 << 31),
        Just(u32::MAX),
        Just(u32::MAX - 7),
        any::<u32>(),
    ]
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        (any::<usize>(), 1..=255u8).prop_map(|(at, x)| Mutation::Flip(at, x)),
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), extreme_u32()).prop_map(|(at, v)| Mutation::SetU32(at, v)),
    ]
}

fn apply(bytes: &mut Vec<u8>, mutation: &Mutation) {
    if bytes.is_empty() {
        return;
    }
    match *mutation {
        Mutation::Flip(at, x) => {
            let n = bytes.len();
            bytes[at % n] ^= x;
        }
        Mutation::Truncate(at) => bytes.truncate(at % bytes.len()),
        Mutation::SetU32(at, v) => {
            let at = at % bytes.len();
            let end = (at + 4).min(bytes.len());
            bytes[at..end].copy_from_slice(&v.to_le_bytes()[..end - at]);
        }
    }
}

/// The offsets of the value fields of a hand-built TIFF's entries (width, height, bits,
/// compression, strip offset, rows per strip, strip bytes) and next-page pointers: where
/// `SetU32` lands most of the time.
fn tiff_fields(bytes: &[u8]) -> Vec<usize> {
    let mut fields = vec![4];
    let mut ifd = u32::from_le_bytes(bytes[4..8].try_into().unwrap()) as usize;
    while ifd != 0 && ifd + 2 <= bytes.len() {
        let entries = u16::from_le_bytes([bytes[ifd], bytes[ifd + 1]]) as usize;
        fields.extend((0..entries).map(|e| ifd + 2 + 12 * e + 8));
        let next = ifd + 2 + 12 * entries;
        fields.push(next);
        ifd = u32::from_le_bytes(bytes[next..next + 4].try_into().unwrap()) as usize;
    }
    fields
}

/// Writes `bytes` to `file`, runs `read`, and checks its peak memory.
fn check_reader(file: &Path, bytes: &[u8], read: impl FnOnce(&Path)) -> Result<(), TestCaseError> {
    std::fs::write(file, bytes).unwrap();
    let peak = peak_of(|| read(file));
    prop_assert!(
        peak <= LIMIT as i64 + MARGIN,
        "peak {peak} bytes over the limit {LIMIT} (+ {MARGIN})"
    );
    Ok(())
}

fn read_volume_file(file: &Path) {
    let _ = count_volume_frames(file);
    if let Ok(frames) = read_volumes(file, &VolumeOptions::default()) {
        assert!(!frames.volumes.is_empty());
    }
}

/// The small images of every codec chain, written once.
fn zarr_images() -> &'static [(&'static str, std::path::PathBuf)] {
    static IMAGES: std::sync::OnceLock<(
        tempfile::TempDir,
        Vec<(&'static str, std::path::PathBuf)>,
    )> = std::sync::OnceLock::new();
    let (_, images) = IMAGES.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let images = zarr::write_all(dir.path());
        (dir, images)
    });
    images
}

/// A copy of directory `from` at `to`.
fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap().flatten() {
        let target = to.join(entry.file_name());
        match entry.file_type().unwrap().is_dir() {
            true => copy_dir(&entry.path(), &target),
            false => drop(std::fs::copy(entry.path(), &target).unwrap()),
        }
    }
}

/// Puts a file's bytes back when dropped, also when a case fails.
struct Restore(std::path::PathBuf, Vec<u8>);

impl Drop for Restore {
    fn drop(&mut self) {
        std::fs::write(&self.0, &self.1).unwrap();
    }
}

thread_local! {
    /// Where this thread's copies of the Zarr images are.
    static WORK: tempfile::TempDir = tempfile::tempdir().unwrap();
    /// A pool of this thread alone: the reader's parallel decoding then allocates where the
    /// counter sees it.
    static ONE_THREAD: rayon::ThreadPool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .use_current_thread()
        .build()
        .unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), failure_persistence: None, ..ProptestConfig::default() })]

    #[test]
    fn mutated_zarr_images_read_or_fail_within_the_limit(
        image in any::<usize>(),
        target in prop_oneof![3 => Just(0usize), 1 => Just(1), 1 => Just(2)],
        file in any::<usize>(),
        from_end in any::<bool>(),
        mutations in prop::collection::vec(mutation(), 1..4),
    ) {
        meshflow::limits::set_memory_limit(LIMIT);
        let images = zarr_images();
        let (name, template) = &images[image % images.len()];
        // This thread's copy of the image: each case changes one file and puts it back after.
        let copy = WORK.with(|work| work.path().join(template.file_name().unwrap()));
        if !copy.exists() {
            copy_dir(template, &copy);
        }
        // A chunk or shard (most cases), the array's metadata, or the group's.
        let chunks = zarr::chunk_files(&copy);
        let array = ["0/zarr.json", "0/.zarray"].map(|f| copy.join(f)).into_iter().find(|f| f.exists());
        let group = ["zarr.json", ".zattrs"].map(|f| copy.join(f)).into_iter().find(|f| f.exists());
        let victim = match target {
            0 => chunks[file % chunks.len()].clone(),
            1 => array.unwrap(),
            _ => group.unwrap(),
        };
        let original = std::fs::read(&victim).unwrap();
        let mut bytes = original.clone();
        let _restore = Restore(victim.clone(), original);
        for mutation in &mutations {
            // Shard indexes and blosc or zstd headers are at the ends: aim there half the time.
            let mutation = match (mutation, from_end) {
                (Mutation::SetU32(at, v), true) => Mutation::SetU32(bytes.len().saturating_sub(1 + at % 40), *v),
                (Mutation::Flip(at, x), true) => Mutation::Flip(bytes.len().saturating_sub(1 + at % 40), *x),
                (other, _) => other.clone(),
            };
            apply(&mut bytes, &mutation);
        }
        std::fs::write(&victim, &bytes).unwrap();
        let peak = peak_of(|| ONE_THREAD.with(|pool| pool.install(|| {
            if let Ok(frames) = read_volumes(&copy, &VolumeOptions::default()) {
                assert!(!frames.volumes.is_empty(), "{name}");
            }
        })));
        prop_assert!(peak <= LIMIT as i64 + MARGIN, "{name}: peak {peak} bytes over the limit");
    }

    #[test]
    fn mutated_tiff_stacks_read_or_fail_within_the_limit(
        pages in 1usize..5,
        (width, height) in (1u32..9, 1u32..9),
        mutations in prop::collection::vec((mutation(), any::<bool>(), any::<usize>()), 1..5),
    ) {
        meshflow::limits::set_memory_limit(LIMIT);
        let dir = tempfile::tempdir().unwrap();
        let mut bytes = small_tiff(pages, width, height);
        let fields = tiff_fields(&bytes);
        for (mutation, on_field, field) in &mutations {
            let mutation = match (mutation, on_field) {
                (Mutation::SetU32(_, v), true) => Mutation::SetU32(fields[field % fields.len()], *v),
                (other, _) => other.clone(),
            };
            apply(&mut bytes, &mutation);
        }
        check_reader(&dir.path().join("stack.tif"), &bytes, read_volume_file)?;
    }

    #[test]
    fn mutated_npy_volumes_read_or_fail_within_the_limit(
        shape in prop::collection::vec(prop_oneof![Just(0u64), 1u64..6, Just(1 << 20), Just(1 << 40), Just(u64::MAX)], 2..6),
        lie in any::<bool>(),
        mutations in prop::collection::vec(mutation(), 0..4),
    ) {
        meshflow::limits::set_memory_limit(LIMIT);
        let dir = tempfile::tempdir().unwrap();
        // The data of a (2, 3, 4, 5) volume under a header that may declare another shape.
        let values: Vec<f64> = (0..120).map(|v| v as f64 * 0.5).collect();
        let declared = if lie { shape } else { vec![2, 3, 4, 5] };
        let mut bytes = npy_bytes(&declared, &values);
        for mutation in &mutations {
            apply(&mut bytes, mutation);
        }
        check_reader(&dir.path().join("volume.npy"), &bytes, read_volume_file)?;
    }

    #[test]
    fn mutated_csv_points_read_or_fail_within_the_limit(
        lines in prop::collection::vec(prop::collection::vec(prop_oneof![
            Just("1.5".to_string()), Just("-2e3".to_string()), Just("nan".to_string()),
            Just("inf".to_string()), Just("1e400".to_string()), Just("x".to_string()),
            Just("".to_string()), Just("#".to_string()), "[ -~]{0,6}",
        ], 0..5), 0..12),
        mutations in prop::collection::vec(mutation(), 0..3),
    ) {
        meshflow::limits::set_memory_limit(LIMIT);
        let dir = tempfile::tempdir().unwrap();
        let text: Vec<String> = lines.iter().map(|fields| fields.join(",")).collect();
        let mut bytes = text.join("\n").into_bytes();
        for mutation in &mutations {
            apply(&mut bytes, mutation);
        }
        check_reader(&dir.path().join("points.csv"), &bytes, |file| {
            if let Ok(frames) = read_points(file) {
                assert!(frames.iter().flatten().all(|p| p.iter().all(|c| c.is_finite())));
            }
        })?;
    }
}

#[test]
fn the_allocator_counts_and_the_limit_holds_for_a_large_declared_stack() {
    meshflow::limits::set_memory_limit(LIMIT);
    let peak = peak_of(|| drop(vec![0u8; 1 << 20]));
    assert!(peak >= 1 << 20, "{peak}");
    // 16 pages of 2048² (268 MB of f32) in a 1 kB file: refused, nothing near it allocated.
    let dir = tempfile::tempdir().unwrap();
    let mut bytes = small_tiff(16, 2, 2);
    let fields = tiff_fields(&bytes);
    for page in 0..16 {
        for (field, value) in [(0, 2048u32), (1, 2048), (7, 2048)] {
            apply(
                &mut bytes,
                &Mutation::SetU32(fields[1 + page * 11 + field], value),
            );
        }
    }
    let file = dir.path().join("large.tif");
    std::fs::write(&file, &bytes).unwrap();
    let peak = peak_of(|| {
        let error = read_volumes(&file, &VolumeOptions::default()).unwrap_err();
        assert!(error.to_string().contains("--memory-limit"), "{error}");
    });
    assert!(peak < 1 << 20, "{peak}");
}
