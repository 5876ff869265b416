//! Contacts in the free numbering: an obstacle contact on one free vertex, or a contact between
//! bodies on the relative coordinate of a stencil of up to four free vertices (Eq. C3).

use nalgebra::Vector3;

use crate::contact::pair::PairContact;
use crate::contact::Contact;

/// A contact in the free numbering.
#[derive(Debug, Clone, Copy)]
pub(crate) struct FreeContact {
    /// Free index of the vertex (for a pair between bodies: of the stencil's first entry).
    pub index: usize,
    /// The contact, on the stencil's relative coordinate.
    pub contact: Contact,
    /// Free vertices and coefficients of the relative coordinate the contact acts on.
    pub stencil: Stencil,
    /// For a contact between bodies: the pair it linearises (`None`: an obstacle contact).
    pub pair: Option<PairContact>,
}

impl FreeContact {
    /// A contact of free vertex `index` with an obstacle.
    pub fn single(index: usize, contact: Contact) -> Self {
        Self {
            index,
            contact,
            stencil: Stencil::single(index),
            pair: None,
        }
    }
}

/// The free vertices and coefficients of a contact's relative coordinate `r = sum_k c_k x_k`
/// (one vertex with coefficient 1 for an obstacle contact; up to four for a pair of bodies).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Stencil {
    /// Number of entries.
    pub len: u8,
    /// Free indices.
    pub index: [usize; 4],
    /// Coefficients.
    pub coef: [f64; 4],
}

impl Stencil {
    /// One vertex with coefficient 1.
    pub fn single(index: usize) -> Self {
        Self {
            len: 1,
            index: [index, 0, 0, 0],
            coef: [1.0, 0.0, 0.0, 0.0],
        }
    }

    /// `(free index, coefficient)` pairs.
    pub fn entries(&self) -> impl Iterator<Item = (usize, f64)> + '_ {
        self.index
            .iter()
            .copied()
            .zip(self.coef.iter().copied())
            .take(self.len as usize)
    }

    /// `sum_k c_k x_k`.
    pub fn apply(&self, x: &[Vector3<f64>]) -> Vector3<f64> {
        self.entries().fold(Vector3::zeros(), |acc, (i, c)| acc + x[i] * c)
    }
}
