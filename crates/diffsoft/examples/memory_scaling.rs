//! How much faster this machine streams memory, and computes in registers, on several threads
//! than on one: the ceiling for any step whose data outgrow the caches (the 52k-tet beam of
//! `thread_scaling`). Two arrays of 16 Mi doubles (128 MB each), `b[i] += 1.0001 a[i]`
//! ten times over, split in equal contiguous parts between the threads; and a loop of
//! dependent multiply-adds per thread that touches no memory.
//!
//! `cargo run --release --example memory_scaling -- [THREADS,...] [ROUNDS]` (defaults: 1,2 and
//! 5). Every round times each thread count once, in order; the first round also touches the
//! pages and is left out.

use std::time::Instant;

use rayon::prelude::*;

const N: usize = 16 << 20;

fn stream(a: &[f64], b: &mut [f64], parts: usize) {
    let chunk = b.len().div_ceil(parts);
    b.par_chunks_mut(chunk).zip(a.par_chunks(chunk)).for_each(|(b, a)| {
        for _ in 0..10 {
            for (y, x) in b.iter_mut().zip(a) {
                *y += 1.0001 * x;
            }
        }
    });
}

fn registers(parts: usize) -> f64 {
    (0..parts)
        .into_par_iter()
        .map(|p| {
            let mut x = 1.0 + p as f64;
            for _ in 0..200_000_000u64 / parts as u64 {
                x = std::hint::black_box(x.mul_add(1.000_000_1, 1e-9));
            }
            x
        })
        .sum()
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let threads: Vec<usize> = args
        .first()
        .map_or("1,2", String::as_str)
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let rounds: usize = args.get(1).map_or(Ok(5), |s| s.parse())?;
    let pools = threads
        .iter()
        .map(|&t| rayon::ThreadPoolBuilder::new().num_threads(t).build())
        .collect::<Result<Vec<_>, _>>()?;
    let a: Vec<f64> = (0..N).map(|i| i as f64).collect();
    let mut b = vec![0.0; N];
    println!("round  threads  stream s  speed-up  registers s  speed-up");
    for round in 0..=rounds {
        let mut base = None;
        for (&t, pool) in threads.iter().zip(&pools) {
            let t0 = Instant::now();
            pool.install(|| stream(&a, &mut b, t));
            let s = t0.elapsed().as_secs_f64();
            let t1 = Instant::now();
            std::hint::black_box(pool.install(|| registers(t)));
            let r = t1.elapsed().as_secs_f64();
            let (s1, r1) = *base.get_or_insert((s, r));
            if round > 0 {
                println!("{round:>5} {t:>8} {s:>9.3} {:>8.2}x {r:>12.3} {:>8.2}x", s1 / s, r1 / r);
            }
        }
    }
    std::hint::black_box(&b);
    Ok(())
}
