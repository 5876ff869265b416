//! A small process-wide memory of eigenvalue ranges ([`super::split_extremes`]), keyed by a
//! fingerprint of every input bit: the same system and time step certified again (one solver
//! setting after another in a sweep) reuses the pair instead of a Lanczos run.

use std::collections::hash_map::DefaultHasher;
use std::hash::{Hash, Hasher};
use std::sync::Mutex;

use super::spectral::EigenMethod;
use super::IterationSystem;

/// Entries kept (the oldest is dropped first).
const CAPACITY: usize = 32;

/// `(fingerprint, (smallest, largest))`, newest last.
static ENTRIES: Mutex<Vec<(Fingerprint, (f64, f64))>> = Mutex::new(Vec::new());

/// Two independent 64-bit hashes of the inputs and their sizes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Fingerprint {
    hashes: [u64; 2],
    sizes: [usize; 4],
}

/// The fingerprint of `(sys, h, method)`.
pub(super) fn fingerprint(sys: &IterationSystem, h: f64, method: EigenMethod) -> Fingerprint {
    let hash = |salt: u64| {
        let mut s = DefaultHasher::new();
        salt.hash(&mut s);
        h.to_bits().hash(&mut s);
        (method as u8).hash(&mut s);
        sys.l.col_ptr.hash(&mut s);
        sys.l.row_idx.hash(&mut s);
        for v in sys.l.values.iter().chain(&sys.mass).chain(&sys.attachment) {
            v.to_bits().hash(&mut s);
        }
        s.finish()
    };
    Fingerprint {
        hashes: [hash(0x9e37_79b9_7f4a_7c15), hash(0xc2b2_ae3d_27d4_eb4f)],
        sizes: [sys.l.n, sys.l.values.len(), sys.mass.len(), sys.attachment.len()],
    }
}

/// The remembered pair for `key`.
pub(super) fn get(key: Fingerprint) -> Option<(f64, f64)> {
    let entries = ENTRIES.lock().ok()?;
    entries.iter().rev().find(|(k, _)| *k == key).map(|(_, v)| *v)
}

/// Remember `value` for `key`.
pub(super) fn put(key: Fingerprint, value: (f64, f64)) {
    if let Ok(mut entries) = ENTRIES.lock() {
        if entries.len() >= CAPACITY {
            entries.remove(0);
        }
        entries.push((key, value));
    }
}

#[cfg(test)]
mod tests {
    use super::super::{split_extremes, split_extremes_uncached};
    use super::*;
    use crate::fem::SymCsc;

    /// A 1-D chain of springs as `L` (tridiagonal, lower triangle stored).
    fn chain(n: usize, k: f64, mass: f64) -> IterationSystem {
        let mut col_ptr = vec![0];
        let (mut row_idx, mut values) = (Vec::new(), Vec::new());
        for j in 0..n {
            let ends = usize::from(j == 0) + usize::from(j + 1 == n);
            row_idx.push(j);
            values.push(k * (2 - ends) as f64 + k * 0.1);
            if j + 1 < n {
                row_idx.push(j + 1);
                values.push(-k);
            }
            col_ptr.push(row_idx.len());
        }
        let l = SymCsc {
            n,
            col_ptr,
            row_idx,
            values,
        };
        IterationSystem::from_parts(l, vec![mass; n], Vec::new()).unwrap()
    }

    /// A repeat returns the computed pair; a changed input (mass, step, stiffness) is computed
    /// afresh.
    #[test]
    fn repeats_are_remembered_and_changes_are_not() {
        let sys = chain(40, 3.0, 0.5);
        let first = split_extremes(&sys, 0.01, EigenMethod::Dense).unwrap();
        assert_eq!(first, split_extremes_uncached(&sys, 0.01, EigenMethod::Dense).unwrap());
        assert!(get(fingerprint(&sys, 0.01, EigenMethod::Dense)).is_some());
        assert_eq!(split_extremes(&sys, 0.01, EigenMethod::Dense).unwrap(), first);
        for (other, h) in [
            (chain(40, 3.0, 0.6), 0.01),
            (chain(40, 3.5, 0.5), 0.01),
            (chain(40, 3.0, 0.5), 0.02),
        ] {
            let key = fingerprint(&other, h, EigenMethod::Dense);
            assert_ne!(key, fingerprint(&sys, 0.01, EigenMethod::Dense));
            let got = split_extremes(&other, h, EigenMethod::Dense).unwrap();
            assert_eq!(got, split_extremes_uncached(&other, h, EigenMethod::Dense).unwrap());
            assert_ne!(got, first);
        }
    }
}
