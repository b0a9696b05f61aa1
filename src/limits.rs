//! What one process may take from the machine on behalf of its input files, and which files
//! named inside other files it may read.
//!
//! Input files are treated as hostile: a 128-byte `.npy` header can declare a terabyte, a
//! glTF buffer URI can name `/etc/passwd` or `/dev/zero`. Two process-wide settings guard
//! against that:
//!
//! - **The memory limit** ([`memory_limit`], [`set_memory_limit`]; the command line's
//!   `--memory-limit`). Every reader checks the size a file *declares* (a header's shape, a
//!   TIFF's pages × page size, a PLY's element counts, a glTF buffer's `byteLength`) against
//!   it before it allocates or decompresses anything ([`check_declared`]); options whose cost
//!   grows without bound (smoothing widths, shell layers) are checked against it too. The
//!   solver's budget for its Cholesky factors is a share of it ([`factor_budget`]). The
//!   default is the machine's physical memory.
//! - **Linked files** ([`linked_files`], [`set_linked_files`]; `--allow-external-files`).
//!   A file named inside another file (glTF `buffers[].uri` and `images[].uri`, OBJ `mtllib`,
//!   MTL `map_Kd`) is read only when it lies in the naming file's directory or below it, as a
//!   regular file, after percent-decoding and following links
//!   ([`crate::format::resolve_linked`]). [`LinkedFiles::Anywhere`] lifts the containment for
//!   trusted data that lives elsewhere; non-regular files (`/dev/zero`, FIFOs) stay refused.
//!
//! Both are process-wide, like rayon's global thread pool, because they describe the process
//! and its machine rather than one call: every reader, however deep, checks against the same
//! numbers without an options argument threaded through each of them.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// The memory limit in bytes; 0 until set (then [`physical_memory`] counts).
static MEMORY_LIMIT: AtomicU64 = AtomicU64::new(0);

/// Whether linked files may lie outside the naming file's directory.
static LINKED_ANYWHERE: AtomicBool = AtomicBool::new(false);

/// Assumed when the machine's memory cannot be read (not Linux, no `/proc`).
const FALLBACK_MEMORY: u64 = 8 << 30;

/// The share of the memory limit the solver's slab factors may take (8.2 GB of 23.4 GB).
const FACTOR_SHARE: f64 = 0.35;

/// The memory limit in bytes: what [`set_memory_limit`] set, else the machine's physical
/// memory.
pub fn memory_limit() -> u64 {
    match MEMORY_LIMIT.load(Ordering::Relaxed) {
        0 => physical_memory(),
        limit => limit,
    }
}

/// Sets the memory limit of this process (0: back to the machine's physical memory).
pub fn set_memory_limit(bytes: u64) {
    MEMORY_LIMIT.store(bytes, Ordering::Relaxed);
}

/// The bytes the solver's slab Cholesky factors may take: 35 % of [`memory_limit`], the rest
/// left to the system, its iterates and the outputs.
pub fn factor_budget() -> usize {
    (memory_limit() as f64 * FACTOR_SHARE) as usize
}

/// The machine's physical memory (`MemTotal` of `/proc/meminfo`), or 8 GiB where it cannot be
/// read.
pub fn physical_memory() -> u64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| {
            let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
            let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
            kib.checked_mul(1024)
        })
        .unwrap_or(FALLBACK_MEMORY)
}

/// A declared size that does not fit the memory limit.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "{what} declares {}, over the memory limit of {} (--memory-limit)",
    format_size(*declared),
    format_size(*limit)
)]
pub struct OverBudget {
    /// What declared it ("shape [1000000000000, 3]", "64 pages of 8192 × 8192").
    pub what: String,
    /// The declared bytes (saturated at `u64::MAX` where the product overflows).
    pub declared: u64,
    pub limit: u64,
}

/// Checks that `bytes` declared by `what` fit the memory limit, before anything is allocated.
pub fn check_declared(what: impl Into<String>, bytes: u64) -> Result<(), OverBudget> {
    let limit = memory_limit();
    if bytes <= limit {
        return Ok(());
    }
    Err(OverBudget {
        what: what.into(),
        declared: bytes,
        limit,
    })
}

/// `count` items of `item_bytes` each, checked against the memory limit; overflow counts as
/// over it.
pub fn check_items(what: impl Into<String>, count: u64, item_bytes: u64) -> Result<(), OverBudget> {
    check_declared(what, count.saturating_mul(item_bytes))
}

/// `1.5G`, `800M`, `64K` or a plain number of bytes (suffixes K, M, G, T: powers of 1024;
/// an optional `B` or `iB` after them).
pub fn parse_size(text: &str) -> Result<u64, String> {
    let trimmed = text.trim();
    let upper = trimmed.to_ascii_uppercase();
    let without_b = upper
        .strip_suffix("IB")
        .or_else(|| upper.strip_suffix('B'))
        .unwrap_or(&upper);
    let (number, shift) = match without_b.chars().last() {
        Some('K') => (&without_b[..without_b.len() - 1], 10),
        Some('M') => (&without_b[..without_b.len() - 1], 20),
        Some('G') => (&without_b[..without_b.len() - 1], 30),
        Some('T') => (&without_b[..without_b.len() - 1], 40),
        _ => (without_b, 0),
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("'{trimmed}' is not a size (e.g. 1.5G, 800M, 4096)"))?;
    let bytes = value * (1u64 << shift) as f64;
    if !(bytes.is_finite() && bytes >= 1.0 && bytes < u64::MAX as f64) {
        return Err(format!("'{trimmed}' is not a positive size"));
    }
    Ok(bytes as u64)
}

/// A size for messages: `4.2 GB`, `512 MB`, `73 kB`, `12 bytes` (decimal units).
pub fn format_size(bytes: u64) -> String {
    const UNITS: [(f64, &str); 4] = [(1e12, "TB"), (1e9, "GB"), (1e6, "MB"), (1e3, "kB")];
    if bytes == u64::MAX {
        return "more than 18 EB".into();
    }
    let value = bytes as f64;
    UNITS
        .iter()
        .find(|(unit, _)| value >= *unit)
        .map(|(unit, name)| format!("{:.1} {name}", value / unit))
        .unwrap_or_else(|| format!("{bytes} bytes"))
}

/// Where a file named inside another file may lie.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LinkedFiles {
    /// In the naming file's directory or below it (the default).
    #[default]
    Contained,
    /// Anywhere (trusted data): absolute paths and `..` are followed.
    Anywhere,
}

/// The linked-file policy of this process.
pub fn linked_files() -> LinkedFiles {
    match LINKED_ANYWHERE.load(Ordering::Relaxed) {
        true => LinkedFiles::Anywhere,
        false => LinkedFiles::Contained,
    }
}

/// Sets the linked-file policy of this process.
pub fn set_linked_files(policy: LinkedFiles) {
    LINKED_ANYWHERE.store(policy == LinkedFiles::Anywhere, Ordering::Relaxed);
}

/// Hands the allocator's free memory back to the system (glibc's `malloc_trim`; nothing
/// elsewhere). Called after a large working set is dropped and before another is built: glibc
/// raises its mmap threshold whenever an mmapped block is freed, so later large blocks come
/// from the heaps and freed ones stay resident. Measured on 200 frames × 48,450 vertices
/// (`bench_paper_torus -- 255 190 200`): the slabs dropped after assembly (4.3 GB) stayed
/// resident under the Cholesky factors built next, and the peak was 11.2 GB instead of 8.6.
pub fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only returns free pages of the allocator's own heaps to the system.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_suffixes() {
        assert_eq!(parse_size("1.5G"), Ok(3 << 29));
        assert_eq!(parse_size("800M"), Ok(800 << 20));
        assert_eq!(parse_size("64k"), Ok(64 << 10));
        assert_eq!(parse_size("2GiB"), Ok(2 << 30));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("-1G").is_err());
        assert!(parse_size("lots").is_err());
        assert!(parse_size("0").is_err());
        assert!(parse_size("nanG").is_err());
    }

    #[test]
    fn sizes_format_in_decimal_units() {
        assert_eq!(format_size(4_200_000_000), "4.2 GB");
        assert_eq!(format_size(73_000), "73.0 kB");
        assert_eq!(format_size(12), "12 bytes");
    }

    #[test]
    fn over_budget_names_declared_size_and_limit() {
        let error = check_items("shape [1000000000000, 4]", 4_000_000_000_000, 8).unwrap_err();
        assert_eq!(error.declared, 32_000_000_000_000);
        let text = error.to_string();
        assert!(
            text.contains("32.0 TB") && text.contains("--memory-limit"),
            "{text}"
        );
        assert!(check_items("overflow", u64::MAX, 2).is_err());
    }
}
