//! A step's loops spread over the pool's threads in two contiguous runs: the stepping thread
//! takes items from the front, the others from the back, each item once, until none is left.
//!
//! Rayon's own splitting ends each loop in a tree of joins; on this VM a thread that waited
//! more than a few tens of microseconds at one of them went to sleep, and waking it took 30 to
//! 60 us more (measured on the 500 I_P bed: the pairs' loop returned 60 us after its last item
//! had ended, a fifth of the loop). Here the stepping thread, once the items are all taken,
//! spins until the last one is done (at most one item's time), and each thread keeps to its
//! own end of the items: a body posed, paired and moved by one thread stays in that core's
//! cache from loop to loop. The results are in item order whichever thread made them.

use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::Mutex;

/// `f` of each of `items`, on the current rayon pool when `par` (the calling thread alone
/// when not, or when the pool has one thread), results in item order.
pub fn spread<I: Send, T: Send>(items: Vec<I>, par: bool, f: impl Fn(I) -> T + Sync) -> Vec<T> {
    let n = items.len();
    let threads = rayon::current_num_threads();
    if !par || n <= 1 || threads <= 1 {
        return items.into_iter().map(f).collect();
    }
    let slots: Vec<Mutex<Option<I>>> = items.into_iter().map(|i| Mutex::new(Some(i))).collect();
    let results: Vec<Mutex<Option<T>>> = (0..n).map(|_| Mutex::new(None)).collect();
    // The items not yet taken: [front, back), packed in one word so that a take from either
    // end sees the other's.
    let range = AtomicU64::new(n as u64);
    let done = AtomicUsize::new(0);
    let take = |from_front: bool| -> Option<usize> {
        let mut now = range.load(Ordering::Acquire);
        loop {
            let (front, back) = (now >> 32, now & 0xffff_ffff);
            if front >= back {
                return None;
            }
            let (next, k) = if from_front {
                ((front + 1) << 32 | back, front)
            } else {
                (front << 32 | (back - 1), back - 1)
            };
            match range.compare_exchange_weak(now, next, Ordering::AcqRel, Ordering::Acquire) {
                Ok(_) => return Some(k as usize),
                Err(seen) => now = seen,
            }
        }
    };
    let work = |from_front: bool| {
        while let Some(k) = take(from_front) {
            let item = (slots[k].lock().unwrap_or_else(|e| e.into_inner()).take())
                .expect("each item is taken once");
            let r = f(item);
            *results[k].lock().unwrap_or_else(|e| e.into_inner()) = Some(r);
            done.fetch_add(1, Ordering::Release);
        }
    };
    rayon::scope(|s| {
        for _ in 1..threads {
            s.spawn(|_| work(false));
        }
        work(true);
        while done.load(Ordering::Acquire) < n {
            std::hint::spin_loop();
        }
    });
    (results.into_iter())
        .map(|r| {
            let r = r.into_inner().unwrap_or_else(|e| e.into_inner());
            r.expect("every item was done")
        })
        .collect()
}

/// Below this many bodies a step runs on one thread: waking the pool every step costs more
/// than the work (measured: 6 bodies spent 3.5 s of system time per second of work).
pub const PARALLEL_MIN_BODIES: usize = 64;

/// Whether a step of `bodies` bodies runs its loops on the thread pool: from
/// [`PARALLEL_MIN_BODIES`] on, and only with more than one thread (with one, handing each loop
/// to the pool's thread and waiting cost 15 to 45 % of a step of 200 to 500 bodies, much of it
/// in futex and sched_yield calls). Serial and parallel loops give the same bytes.
pub fn parallel(bodies: usize) -> bool {
    bodies >= PARALLEL_MIN_BODIES && rayon::current_num_threads() > 1
}

/// Runs `f`, a loop of steps, on a thread of rayon's pool (the caller waits), so that a step's
/// loops are handed to the pool's other threads directly instead of each through the pool's
/// queue to a sleeping thread and back (with the steps keeping the pool awake, `Awake`: 0.95x
/// the time of 1000 steps of the 2000 I_P bed on 2 threads). The results are the same wherever
/// the steps run.
pub fn on_pool<R: Send>(f: impl FnOnce() -> R + Send) -> R {
    rayon::scope(|_| f())
}

/// Keeps the pool's other threads looking for work through one step (until dropped): a step
/// hands out six loops, and between two of them a worker that found nothing for a few
/// microseconds went to sleep; this VM then took 30 to 45 us to wake it for the next loop
/// (measured: the second thread's first item of the posing loop, 2000 I_P bed), a fifth of
/// that loop. Each other thread of the pool runs one copy, which takes work while there is
/// some and gives the processor back to the scheduler while there is none; it ends with the
/// step, or after [`AWAKE_IDLE`] without work or [`AWAKE_MAX`] in all (a copy started inside
/// one of the step's own loops, or on a pool shared with other work, so holds a loop up for
/// a bounded time at most, never forever). Only speed depends on it.
pub struct Awake(std::sync::Arc<std::sync::atomic::AtomicBool>);

/// An [`Awake`] thread gives up after this long without work, or this long in all.
const AWAKE_IDLE: std::time::Duration = std::time::Duration::from_micros(200);

const AWAKE_MAX: std::time::Duration = std::time::Duration::from_millis(50);

impl Awake {
    /// Starts the other threads looking for work (they stop when this is dropped).
    #[allow(clippy::new_without_default)]
    pub fn new() -> Awake {
        use std::sync::atomic::Ordering;
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stepper = rayon::current_thread_index();
        let end = stop.clone();
        rayon::spawn_broadcast(move |ctx| {
            if Some(ctx.index()) == stepper {
                return;
            }
            let born = std::time::Instant::now();
            let mut busy = born;
            while !end.load(Ordering::Acquire) {
                if rayon::yield_now() == Some(rayon::Yield::Executed) {
                    busy = std::time::Instant::now();
                } else if busy.elapsed() > AWAKE_IDLE || born.elapsed() > AWAKE_MAX {
                    return;
                } else {
                    std::thread::yield_now();
                }
            }
        });
        Awake(stop)
    }
}

impl Drop for Awake {
    fn drop(&mut self) {
        self.0.store(true, std::sync::atomic::Ordering::Release);
    }
}

/// `filter_map` over `items`, in parallel when `par`; the result is in item order either way.
pub fn filter_map_maybe_par<T: Sync, U: Send>(
    items: &[T],
    par: bool,
    f: impl Fn(&T) -> Option<U> + Sync + Send,
) -> Vec<U> {
    if par {
        items.par_iter().filter_map(f).collect()
    } else {
        items.iter().filter_map(f).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pool(threads: usize) -> rayon::ThreadPool {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("a thread pool")
    }

    #[test]
    fn results_come_in_item_order_on_any_number_of_threads() {
        let items: Vec<u64> = (0..1000).collect();
        // Uneven work, so that the threads meet at different places each time.
        let f = |i: u64| (0..(i % 17) * 100).fold(i, |a, k| a.wrapping_mul(31).wrapping_add(k));
        let want: Vec<u64> = items.iter().map(|&i| f(i)).collect();
        for threads in [1, 2, 3, 4] {
            for _ in 0..20 {
                let got = pool(threads).install(|| spread(items.clone(), true, f));
                assert_eq!(got, want, "{threads} threads");
            }
        }
        assert_eq!(spread(items.clone(), true, f), want, "outside any pool");
        assert!(spread(Vec::<u64>::new(), true, f).is_empty());
    }

    #[test]
    fn both_ends_are_worked_and_each_item_once() {
        let p = pool(2);
        let hits: Vec<AtomicUsize> = (0..400).map(|_| AtomicUsize::new(0)).collect();
        let who = p.install(|| {
            spread((0..400).collect(), true, |i: usize| {
                hits[i].fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(std::time::Duration::from_micros(50));
                rayon::current_thread_index()
            })
        });
        assert!(hits.iter().all(|h| h.load(Ordering::Relaxed) == 1));
        // The caller's items are a run from the front, the other thread's a run from the back.
        let first = who[0];
        let switch = who.iter().position(|&t| t != first).unwrap_or(400);
        assert!(switch < 400, "the other thread took no item");
        assert!(who[switch..].iter().all(|&t| t != first), "{who:?}");
    }

    #[test]
    fn a_pool_whose_other_thread_is_busy_still_finishes() {
        let p = pool(2);
        let (tx, rx) = std::sync::mpsc::channel::<()>();
        p.install(|| {
            rayon::join(
                // The other thread is held in this job until the spread is over.
                move || rx.recv().ok(),
                || {
                    let got = spread((0..100).collect(), true, |i: u32| i * 2);
                    assert_eq!(got, (0..100).map(|i| i * 2).collect::<Vec<_>>());
                    tx.send(()).ok();
                },
            )
        });
    }
}
