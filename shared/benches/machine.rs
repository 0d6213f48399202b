//! What the machine gives this hour, so that throughput figures from different runs can be
//! compared: the effective clock of one core and the latency of a load that misses each level
//! of the cache. `make bench` runs it before and after the DEM rows (`pipelines/bench-dem.sh`).
//!
//! Why: on the 2-core development VM the same `dem` code, with the same instruction count
//! (callgrind), has run 1.6-2.2x slower on one host than on another, while compute-bound
//! kernels ran at the same speed. A step of `dem` reads a few MB to a hundred MB of bodies,
//! contacts and structures, so it is sensitive to how much of the shared last-level cache the
//! VM's neighbours leave it, and on which processor the VM runs; these lines say on which host,
//! and in which kind of hour, a run was measured.
//!
//! - Processor: the model as the VM reports it (name, family, model and stepping from
//!   `/proc/cpuinfo`) and its caches (`/sys/devices/system/cpu/cpu0/cache`): the VM may be
//!   put on another kind of host from one day to the next (both an Intel Xeon and an AMD EPYC
//!   have been seen), which changes every figure.
//! - Clock: a chain of dependent integer or-multiplies, timed (4 cycles a link on current
//!   x86-64 cores, so the line also gives the clock those cores run at).
//! - Latency: a random cyclic chain of pointers, one per 64-byte line, over a working set of
//!   each size, walked for a fixed number of dependent loads (a load cannot start before the
//!   last one ends, so the time per load is the latency of wherever the set lives, page walks
//!   included).
//! - Cross-core round trip: two threads hand one cache line back and forth through an atomic
//!   flag, timed per round trip. This is what a step's loops pay each time a body posed,
//!   paired or moved by one thread is next read by the other. On the VM the two processors are
//!   placed by the host: the round trip has measured 56-89 ns in some minutes and
//!   325-350 ns in others, and the 2-thread `dem` runs of the 500 I_P bed took 0.74-0.87 s and
//!   1.35-1.57 s with them (1 thread: 1.28-1.32 s), so the 2-thread rows need this line.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;
use std::time::Instant;

/// Nanoseconds per link of a chain of dependent `x = x * (x | 1)` on one core (an `or` and an
/// integer multiply, 1 + 3 cycles of latency on current x86-64 cores, so 4 / ns is the clock in
/// GHz there): the core's own speed, without memory.
fn chain_ns() -> f64 {
    const LINKS: u64 = 200_000_000;
    let mut x: u64 = black_box(1);
    let clock = Instant::now();
    for _ in 0..LINKS {
        // Not affine, so the compiler cannot fold or reorder the chain: `or`, then multiply.
        x = x.wrapping_mul(x | 1);
    }
    let secs = clock.elapsed().as_secs_f64();
    black_box(x);
    secs / LINKS as f64 * 1e9
}

/// Nanoseconds per dependent load over a working set of `bytes` (a random cycle through one
/// word per 64-byte line).
fn latency_ns(bytes: usize) -> f64 {
    const STRIDE: usize = 64 / std::mem::size_of::<usize>();
    let lines = bytes / 64;
    // A random cyclic order of the lines (it only has to defeat prefetching).
    let mut order: Vec<usize> = (0..lines).collect();
    order.shuffle(&mut ChaCha8Rng::seed_from_u64(25));
    let mut chain = vec![0usize; lines * STRIDE];
    for k in 0..lines {
        chain[order[k] * STRIDE] = order[(k + 1) % lines] * STRIDE;
    }
    let mut at = order[0] * STRIDE;
    // Once round the cycle to bring the set in, then timed.
    for _ in 0..lines {
        at = chain[at];
    }
    let loads = 20_000_000;
    let clock = Instant::now();
    for _ in 0..loads {
        at = chain[at];
    }
    let secs = clock.elapsed().as_secs_f64();
    black_box(at);
    secs / loads as f64 * 1e9
}

/// Nanoseconds per round trip of a cache line between two threads (on a machine of two
/// processors or more, the scheduler puts them on two): one sets a flag, the other sees it and
/// clears it, and so on. `None` with one processor (the two would take turns on it).
fn round_trip_ns() -> Option<f64> {
    use std::sync::atomic::{AtomicBool, Ordering};
    if std::thread::available_parallelism().map_or(1, |n| n.get()) < 2 {
        return None;
    }
    const TRIPS: u32 = 500_000;
    let flag = AtomicBool::new(false);
    let secs = std::thread::scope(|s| {
        s.spawn(|| {
            for _ in 0..TRIPS {
                while !flag.load(Ordering::Acquire) {
                    std::hint::spin_loop();
                }
                flag.store(false, Ordering::Release);
            }
        });
        let clock = Instant::now();
        for _ in 0..TRIPS {
            flag.store(true, Ordering::Release);
            while flag.load(Ordering::Acquire) {
                std::hint::spin_loop();
            }
        }
        clock.elapsed().as_secs_f64()
    });
    Some(secs / f64::from(TRIPS) * 1e9)
}

/// The processor as `/proc/cpuinfo` names it: model name, family, model and stepping of the
/// first CPU listed ("unknown" for what it does not say).
fn processor() -> String {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |key: &str| {
        info.lines()
            .filter_map(|line| line.split_once(':'))
            .find(|(k, _)| k.trim() == key)
            .map_or_else(|| "unknown".to_string(), |(_, v)| v.trim().to_string())
    };
    format!(
        "{} (family {}, model {}, stepping {})",
        field("model name"),
        field("cpu family"),
        field("model"),
        field("stepping")
    )
}

/// The first CPU's data and unified caches, as "L1d 32K, L2 1024K (CPUs 0), L3 32768K
/// (CPUs 0-1)" (with the CPUs sharing each); empty when `/sys` does not list them.
fn caches() -> String {
    let dir = "/sys/devices/system/cpu/cpu0/cache";
    let read = |index: usize, name: &str| {
        std::fs::read_to_string(format!("{dir}/index{index}/{name}"))
            .map(|s| s.trim().to_string())
            .ok()
    };
    (0..8)
        .filter_map(|k| {
            let (level, kind, size) = (read(k, "level")?, read(k, "type")?, read(k, "size")?);
            let shared = read(k, "shared_cpu_list").unwrap_or_default();
            match kind.as_str() {
                "Instruction" => None,
                "Data" => Some(format!("L{level}d {size}")),
                _ => Some(format!("L{level} {size} (CPUs {shared})")),
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn main() {
    println!("machine: {}; caches: {}", processor(), caches());
    let link = chain_ns();
    println!(
        "machine: dependent or-multiply {link:.3} ns (4 cycles on x86-64: {:.2} GHz)",
        4.0 / link
    );
    let cells: Vec<String> = [32 << 10, 512 << 10, 4 << 20, 16 << 20, 64 << 20]
        .into_iter()
        .map(|bytes: usize| {
            let size = match bytes >> 20 {
                0 => format!("{} KiB", bytes >> 10),
                mib => format!("{mib} MiB"),
            };
            format!("{size} {:.1} ns", latency_ns(bytes))
        })
        .collect();
    println!("machine: load latency by working set: {}", cells.join(", "));
    match round_trip_ns() {
        Some(ns) => println!("machine: cache line between two threads, round trip {ns:.0} ns"),
        None => println!("machine: cache line between two threads: one processor only"),
    }
}
