//! A dense Cholesky factorisation in f64, for the coarsest level of the multigrid hierarchy
//! (at most a few hundred unknowns, factored once per step).

/// `A = L L^T` of a symmetric positive definite matrix, `L` stored row-major in full.
#[derive(Clone, Debug, Default)]
pub struct DenseCholesky {
    n: usize,
    l: Vec<f64>,
}

impl DenseCholesky {
    /// Factors the `n` x `n` row-major matrix `a` (only its lower triangle is read). A pivot that
    /// is not positive (a row the caller left empty, or round-off on a singular matrix) makes its
    /// unknown decouple: that column of `L` becomes a unit column, so the solve returns the
    /// right-hand side there instead of dividing by zero.
    pub fn factor(&mut self, a: &[f64], n: usize) {
        self.n = n;
        self.l.clear();
        self.l.extend_from_slice(&a[..n * n]);
        let l = &mut self.l;
        for j in 0..n {
            let mut d = l[j * n + j];
            for k in 0..j {
                d -= l[j * n + k] * l[j * n + k];
            }
            let scale = (0..n).map(|i| a[i * n + i].abs()).fold(0.0, f64::max);
            let positive = d > 1e-12 * scale && d.is_finite();
            if !positive {
                l[j * n + j] = 1.0;
                for k in 0..j {
                    l[j * n + k] = 0.0;
                }
                for i in j + 1..n {
                    l[i * n + j] = 0.0;
                }
                continue;
            }
            let djj = d.sqrt();
            l[j * n + j] = djj;
            for i in j + 1..n {
                let mut s = l[i * n + j];
                for k in 0..j {
                    s -= l[i * n + k] * l[j * n + k];
                }
                l[i * n + j] = s / djj;
            }
        }
        for i in 0..n {
            for j in i + 1..n {
                l[i * n + j] = 0.0;
            }
        }
    }

    /// Solves `A x = b` in place.
    pub fn solve(&self, b: &mut [f64]) {
        let (n, l) = (self.n, &self.l);
        for i in 0..n {
            let mut s = b[i];
            for k in 0..i {
                s -= l[i * n + k] * b[k];
            }
            b[i] = s / l[i * n + i];
        }
        for i in (0..n).rev() {
            let mut s = b[i];
            for k in i + 1..n {
                s -= l[k * n + i] * b[k];
            }
            b[i] = s / l[i * n + i];
        }
    }

    pub fn len(&self) -> usize {
        self.n
    }

    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_an_spd_system_and_decouples_an_empty_row() {
        let n = 4;
        // A tridiagonal SPD matrix with row and column 2 left empty.
        let mut a = vec![0.0; n * n];
        for i in [0, 1, 3] {
            a[i * n + i] = 4.0;
        }
        a[1] = -1.0;
        a[n] = -1.0;
        let mut f = DenseCholesky::default();
        f.factor(&a, n);
        let mut x = vec![1.0, 2.0, 5.0, 3.0];
        f.solve(&mut x);
        assert!((4.0 * x[0] - x[1] - 1.0).abs() < 1e-12);
        assert!((-x[0] + 4.0 * x[1] - 2.0).abs() < 1e-12);
        assert_eq!(x[2], 5.0);
        assert!((4.0 * x[3] - 3.0).abs() < 1e-12);
    }
}
