//! Subnormal numbers off while the solver runs: flush-to-zero (results below the smallest
//! normal number become 0) and denormals-are-zero (subnormal inputs read as 0).
//!
//! **Why.** The preconditioner's slab factors are stored in single precision
//! (`flow::solve`), whose smallest normal number is `1.2e-38`. At mid-range `α` the
//! factors' fill decays through that range, and on some processors an arithmetic operation
//! with a subnormal operand or result takes a microcode assist: on the machine of issue 38
//! (a 2-core cloud x86-64) a multiply-add cost 35× a normal one, and the factorization at
//! `α = 0.01` on the 128 × 95 × 20 torus took 5.3 s against 0.9 s with the modes on, the
//! iterations (14) and the residual unchanged. Values below `1.2e-38` relative to entries of
//! order 1 are far below single precision's own rounding (`6e-8`), so flushing them changes
//! nothing the solver can see; the tests that compare against independent solutions to
//! `1e-15` hold as they are.
//!
//! **How.** The modes are bits of a per-thread control register (x86-64: `MXCSR` bits 15 and
//! 6; AArch64: `FPCR.FZ`, bit 24, which flushes inputs and outputs alike). [`flushed`] sets
//! them on the calling thread and on every thread of the current rayon pool (the threads that
//! factorize and sweep), runs the kernel, and restores each thread's own previous mode when
//! the last scope that holds the thread ends, also when the kernel panics, so a caller's floating-point mode (NumPy's, in Python) is
//! untouched on return. On other processors it only runs the kernel.
//!
//! Rust's reference calls a changed mode undefined behaviour: the compiler folds constants
//! with gradual underflow while the processor then flushes, so code that relies on subnormal
//! results may see either. The kernels run here never rely on them (they are below single
//! precision's rounding of the factors they arise in), and the modes are on only while the
//! kernels run. Written by hand: no
//! maintained crate sets these registers scoped over a thread pool (the `no_denormals` crate
//! covers the calling thread only), and each is one instruction. [`set_enabled`] turns
//! flushing off for the whole process (benchmarks compare the two).

use std::cell::Cell;
use std::sync::atomic::{AtomicBool, Ordering};

static ENABLED: AtomicBool = AtomicBool::new(true);

/// Whether [`flushed`] sets the modes (default `true`); `false` runs kernels in the caller's
/// mode, to measure what subnormals cost.
pub fn set_enabled(enabled: bool) {
    ENABLED.store(enabled, Ordering::Relaxed);
}

/// Whether [`flushed`] sets the modes.
pub fn enabled() -> bool {
    ENABLED.load(Ordering::Relaxed)
}

/// Runs `kernel` with flush-to-zero and denormals-are-zero on the calling thread and on every
/// thread of the current rayon pool, each thread's mode restored afterwards (module docs).
pub fn flushed<R>(kernel: impl FnOnce() -> R) -> R {
    if !enabled() || !register::SUPPORTED {
        return kernel();
    }
    enter();
    rayon::broadcast(|_| enter());
    let _leave = Leave;
    kernel()
}

thread_local! {
    /// Per thread: how many [`flushed`] scopes hold it, and its mode before the first.
    /// Counting per thread keeps the modes right when several threads (ranks played by
    /// threads, Python threads) run kernels on one pool at once: a pool thread is restored
    /// when the last scope leaves it, whatever the order.
    static SCOPES: Cell<(u32, u64)> = const { Cell::new((0, 0)) };
}

fn enter() {
    SCOPES.with(|scopes| {
        let (depth, before) = scopes.get();
        let before = if depth == 0 {
            register::flush()
        } else {
            before
        };
        scopes.set((depth + 1, before));
    });
}

fn leave() {
    SCOPES.with(|scopes| {
        let (depth, before) = scopes.get();
        if depth == 1 {
            register::set(before);
        }
        scopes.set((depth.saturating_sub(1), before));
    });
}

/// Leaves the scope on every thread it entered, also when the kernel panics.
struct Leave;

impl Drop for Leave {
    fn drop(&mut self) {
        rayon::broadcast(|_| leave());
        leave();
    }
}

/// Whether flush-to-zero is on for the calling thread: `false` where the processor has no such
/// mode here.
pub fn flushing_on_this_thread() -> bool {
    register::SUPPORTED && register::get() & register::FLUSH_BITS == register::FLUSH_BITS
}

#[cfg(target_arch = "x86_64")]
mod register {
    pub const SUPPORTED: bool = true;
    /// `MXCSR.FTZ` (bit 15) and `MXCSR.DAZ` (bit 6).
    pub const FLUSH_BITS: u64 = (1 << 15) | (1 << 6);

    pub fn get() -> u64 {
        let mut csr: u32 = 0;
        // SAFETY: `stmxcsr` stores the 32-bit MXCSR to the given address, a live local.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack, preserves_flags));
        }
        u64::from(csr)
    }

    pub fn set(value: u64) {
        let csr = value as u32;
        // SAFETY: `ldmxcsr` loads MXCSR from a value `get` read (or it with the flush bits);
        // no reserved bit is set, so it cannot fault.
        unsafe {
            std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack, readonly, preserves_flags));
        }
    }

    /// Sets the flush bits and returns the previous value.
    pub fn flush() -> u64 {
        let previous = get();
        set(previous | FLUSH_BITS);
        previous
    }
}

#[cfg(target_arch = "aarch64")]
mod register {
    pub const SUPPORTED: bool = true;
    /// `FPCR.FZ` (bit 24).
    pub const FLUSH_BITS: u64 = 1 << 24;

    pub fn get() -> u64 {
        let fpcr: u64;
        // SAFETY: reading FPCR has no side effects.
        unsafe {
            std::arch::asm!("mrs {}, fpcr", out(reg) fpcr, options(nomem, nostack, preserves_flags));
        }
        fpcr
    }

    pub fn set(value: u64) {
        // SAFETY: writes back a value `get` read (or it with FZ), no reserved bit changed.
        unsafe {
            std::arch::asm!("msr fpcr, {}", in(reg) value, options(nomem, nostack, preserves_flags));
        }
    }

    /// Sets the flush bit and returns the previous value.
    pub fn flush() -> u64 {
        let previous = get();
        set(previous | FLUSH_BITS);
        previous
    }
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
mod register {
    pub const SUPPORTED: bool = false;
    pub const FLUSH_BITS: u64 = 0;

    pub fn get() -> u64 {
        0
    }

    pub fn set(_: u64) {}

    pub fn flush() -> u64 {
        0
    }
}
