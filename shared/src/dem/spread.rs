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
