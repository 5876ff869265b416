//! [`diffsoft::alloc::thread_peak`] measures the calling thread's heap growth only: another
//! thread allocating at the same time does not show in it, a nested scope is measured from its
//! own start, and the enclosing scope's peak includes the nested one's. Its own test binary:
//! the counting allocator is global and the allocation tests count every thread's calls.

use std::sync::Barrier;

use diffsoft::alloc::{thread_peak, Counting};

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const MB: usize = 1 << 20;

#[test]
fn a_threads_peak_excludes_other_threads_and_nests() {
    let (start, end) = (Barrier::new(2), Barrier::new(2));
    let (own, other) = std::thread::scope(|s| {
        let own = s.spawn(|| {
            thread_peak(|| {
                start.wait();
                let a = vec![1u8; MB];
                // The other thread holds 32 MB while this one holds 1 MB.
                end.wait();
                a.len()
            })
        });
        let other = s.spawn(|| {
            start.wait();
            let b = vec![2u8; 32 * MB];
            end.wait();
            b.len()
        });
        (own.join().unwrap(), other.join().unwrap())
    });
    assert_eq!((own.0, other), (MB, 32 * MB));
    let peak = own.1.expect("the counting allocator is installed");
    assert!((MB..2 * MB).contains(&peak), "own peak {peak} bytes");

    // Nested: the inner scope counts from its start; the outer sees the inner's peak on top
    // of what it held then; memory freed inside that was allocated before lowers the count.
    let held = vec![0u8; 4 * MB];
    let ((inner, outer_len), outer) = thread_peak(|| {
        let a = vec![0u8; 2 * MB];
        let (_, inner) = thread_peak(|| {
            drop(held);
            vec![0u8; 3 * MB].len()
        });
        (inner, a.len())
    });
    assert_eq!(outer_len, 2 * MB);
    let (inner, outer) = (inner.unwrap(), outer.unwrap());
    // Inner: +3 MB at most (after -4 MB), so its peak is 0.
    assert!(inner < MB / 2, "inner peak {inner}");
    // Outer: 2 MB before the inner scope; the inner scope never rose above its start.
    assert!((2 * MB..3 * MB).contains(&outer), "outer peak {outer}");
}
