//! Small dense kernels of the square-root UKF: column-major, in place, allocation-free.
//!
//! Triangular factors are **lower** with a non-negative diagonal (`P = L·Lᵀ`), stored
//! column-major in an `n × n` slice: element `(i, j)` at `i + j·n`.

use nalgebra::{DMatrix, SymmetricEigen};

/// The rank-one update or downdate of a Cholesky factor lost positive definiteness at `column`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DowndateFailed {
    /// Column (0-based) where `L[k,k]² + σ·v[k]²` was not positive.
    pub column: usize,
}

/// `L ← chol(L·Lᵀ + sign·v·vᵀ)` for lower `L` (`n × n`, column-major), `sign = ±1`. `v` is
/// overwritten. Fails (leaving `L` partly modified) when the result is not positive definite
/// or not finite: callers that must recover keep a copy.
pub fn cholupdate(l: &mut [f64], n: usize, v: &mut [f64], sign: f64) -> Result<(), DowndateFailed> {
    debug_assert!(l.len() >= n * n && v.len() >= n);
    for k in 0..n {
        let lkk = l[k + k * n];
        let vk = v[k];
        if vk == 0.0 {
            continue; // nothing to rotate into this column
        }
        let r2 = lkk * lkk + sign * vk * vk;
        if !(r2 > 0.0 && r2.is_finite()) || (sign < 0.0 && lkk <= 0.0) {
            return Err(DowndateFailed { column: k });
        }
        let r = r2.sqrt();
        let col = &mut l[k * n..(k + 1) * n];
        col[k] = r;
        if sign > 0.0 {
            // Givens rotation of [L[:,k], v]: defined for a zero pivot too
            let (c, s) = (lkk / r, vk / r);
            for i in k + 1..n {
                let (li, vi) = (col[i], v[i]);
                col[i] = c * li + s * vi;
                v[i] = c * vi - s * li;
            }
        } else {
            // hyperbolic rotation
            let (c, s) = (r / lkk, vk / lkk);
            let inv_c = lkk / r;
            for i in k + 1..n {
                col[i] = (col[i] - s * v[i]) * inv_c;
                v[i] = c * v[i] - s * col[i];
            }
        }
    }
    Ok(())
}

/// `Σ a[i]·b[i]` with four independent accumulators (vectorisable; the rounding differs from
/// a sequential sum only in the order of additions).
#[inline(always)]
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; 4];
    let chunks = n / 4;
    for c in 0..chunks {
        let i = 4 * c;
        acc[0] += a[i] * b[i];
        acc[1] += a[i + 1] * b[i + 1];
        acc[2] += a[i + 2] * b[i + 2];
        acc[3] += a[i + 3] * b[i + 3];
    }
    let mut s = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for i in 4 * chunks..n {
        s += a[i] * b[i];
    }
    s
}

/// Lower factor `L = Rᵀ` of the QR decomposition of `a` (`rows × n`, column-major, destroyed),
/// with the signs chosen so that `L` has a non-negative diagonal: `L·Lᵀ = aᵀ·a`, and `L` is the
/// Cholesky factor of `aᵀ·a`. Householder reflections; `l` is `n × n` (zeroed above the
/// diagonal). When the last `tail` rows of `a` form an upper-triangular block (a square root of
/// a noise covariance, transposed), the reflections skip the rows known to be zero.
pub fn qr_lower(a: &mut [f64], rows: usize, n: usize, tail: usize, l: &mut [f64]) {
    debug_assert!(a.len() >= rows * n && l.len() >= n * n && tail <= rows);
    let steps = n.min(rows);
    for k in 0..steps {
        // rows k..end can be non-zero in column k (and in the columns right of it, the
        // triangular tail has zeros below row rows − tail + k)
        let end = (rows - tail + k + 1).min(rows);
        let (head, rest) = a.split_at_mut((k + 1) * rows);
        let colk = &mut head[k * rows..];
        let norm = dot(&colk[k..end], &colk[k..end]).sqrt();
        if norm == 0.0 {
            continue;
        }
        let alpha = if colk[k] > 0.0 { -norm } else { norm };
        colk[k] -= alpha; // v = x − α·e_k, stored in place
                          // vᵀv = |x|² − 2α·x_k + α² = 2α² − 2α·x_k (x_k the original entry)
        let vnorm2 = dot(&colk[k..end], &colk[k..end]);
        if vnorm2 > 0.0 {
            let scale = 2.0 / vnorm2;
            let v = &colk[k..end];
            for j in 0..n - k - 1 {
                let cj = &mut rest[j * rows + k..j * rows + end];
                let f = scale * dot(v, cj);
                for (c, vi) in cj.iter_mut().zip(v) {
                    *c -= f * vi;
                }
            }
        }
        colk[k] = alpha;
    }
    // L[j, i] = sign_i · R[i, j] for j ≥ i
    for i in 0..n {
        let rii = if i < rows { a[i + i * rows] } else { 0.0 };
        let sgn = if rii < 0.0 { -1.0 } else { 1.0 };
        for j in 0..n {
            l[j + i * n] = if j < i || i >= rows {
                0.0
            } else {
                sgn * a[i + j * rows]
            };
        }
    }
}

/// Solve `L·x = b` in place (`L` lower, `n × n` column-major). A zero pivot gives ±inf/NaN:
/// callers check finiteness.
pub fn solve_lower(l: &[f64], n: usize, b: &mut [f64]) {
    for j in 0..n {
        b[j] /= l[j + j * n];
        let bj = b[j];
        for i in j + 1..n {
            b[i] -= l[i + j * n] * bj;
        }
    }
}

/// Solve `Lᵀ·x = b` in place (`L` lower, `n × n` column-major).
pub fn solve_lower_transpose(l: &[f64], n: usize, b: &mut [f64]) {
    for j in (0..n).rev() {
        let mut s = b[j];
        for i in j + 1..n {
            s -= l[i + j * n] * b[i];
        }
        b[j] = s / l[j + j * n];
    }
}

/// Cholesky factor (lower, column-major) of a symmetric positive semi-definite matrix `p`
/// (`n × n`, column-major; only the lower triangle is read). Zero pivots are accepted when the
/// rest of their column is zero too (a state without noise); returns the failing row otherwise.
pub fn cholesky_psd(p: &[f64], n: usize) -> Result<Vec<f64>, usize> {
    let mut l = vec![0.0; n * n];
    for j in 0..n {
        let pjj = p[j + j * n];
        // pivots are judged against their own diagonal entry, so a well-posed but badly scaled
        // covariance (angles in 1e-10 rad², stiffness in 1e8 (N/m)²) is not called singular
        let tiny = 1e-13 * pjj.abs();
        let mut d = pjj;
        for k in 0..j {
            d -= l[j + k * n] * l[j + k * n];
        }
        if !d.is_finite() || d < -tiny {
            return Err(j);
        }
        if d <= tiny {
            // semi-definite direction: the column below must vanish too
            for i in j + 1..n {
                let mut s = p[i + j * n];
                for k in 0..j {
                    s -= l[i + k * n] * l[j + k * n];
                }
                let scale = (p[i + i * n].abs() * pjj.abs()).sqrt();
                if s.abs() > 1e-7 * scale {
                    return Err(j);
                }
            }
            continue;
        }
        let djj = d.sqrt();
        l[j + j * n] = djj;
        for i in j + 1..n {
            let mut s = p[i + j * n];
            for k in 0..j {
                s -= l[i + k * n] * l[j + k * n];
            }
            l[i + j * n] = s / djj;
        }
    }
    Ok(l)
}

/// The nearest (Frobenius) symmetric positive definite matrix to `p` with eigenvalues at least
/// `floor_rel` of the largest one, returned as its lower Cholesky factor. The recovery path of a
/// failed downdate: allocates, never fails for finite input.
pub fn nearest_spd_factor(p: &[f64], n: usize, floor_rel: f64) -> Vec<f64> {
    let m = DMatrix::from_fn(n, n, |i, j| 0.5 * (p[i + j * n] + p[j + i * n]));
    let eig = SymmetricEigen::new(m);
    let top = eig.eigenvalues.iter().fold(0.0_f64, |a, &b| a.max(b.abs()));
    let floor = (floor_rel * top).max(f64::MIN_POSITIVE.sqrt());
    let lam = eig.eigenvalues.map(|v| v.max(floor));
    let q = &eig.eigenvectors;
    let rebuilt = q * DMatrix::from_diagonal(&lam) * q.transpose();
    let flat: Vec<f64> = (0..n * n).map(|k| rebuilt[(k % n, k / n)]).collect();
    // the clipped matrix is positive definite by construction; guard against rounding anyway
    cholesky_psd(&flat, n).unwrap_or_else(|_| {
        let mut l = vec![0.0; n * n];
        for i in 0..n {
            l[i + i * n] = floor.sqrt();
        }
        l
    })
}

/// The factor of `saved·savedᵀ + Σ signᵢ·vᵢ·vᵢᵀ`, projected onto the positive definite cone:
/// the repair after a failed [`cholupdate`] (allocates).
pub fn repaired_factor(saved: &[f64], n: usize, updates: &[(&[f64], f64)]) -> Vec<f64> {
    let mut pm = outer_lower(saved, n);
    for (v, sign) in updates {
        for j in 0..n {
            for i in 0..n {
                pm[i + j * n] += sign * v[i] * v[j];
            }
        }
    }
    nearest_spd_factor(&pm, n, 1e-12)
}

/// [`cholupdate`] that repairs instead of failing (offline paths; allocates a copy): returns
/// whether a repair was needed.
pub fn cholupdate_or_repair(l: &mut [f64], n: usize, v: &mut [f64], sign: f64) -> bool {
    let (saved, keep) = (l[..n * n].to_vec(), v[..n].to_vec());
    if cholupdate(l, n, v, sign).is_ok() {
        return false;
    }
    l[..n * n].copy_from_slice(&repaired_factor(&saved, n, &[(&keep, sign)]));
    true
}

/// `P = L·Lᵀ` (column-major, full).
pub fn outer_lower(l: &[f64], n: usize) -> Vec<f64> {
    let mut p = vec![0.0; n * n];
    for j in 0..n {
        for i in 0..n {
            let mut s = 0.0;
            for k in 0..=i.min(j) {
                s += l[i + k * n] * l[j + k * n];
            }
            p[i + j * n] = s;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn spd(n: usize, seed: u64) -> Vec<f64> {
        // A·Aᵀ + n·I from a deterministic pseudo-random A
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let a: Vec<f64> = (0..n * n).map(|_| next()).collect();
        let mut p = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                p[i + j * n] = (0..n).map(|k| a[i + k * n] * a[j + k * n]).sum::<f64>();
            }
            p[i + i * n] += n as f64 * 0.1;
        }
        p
    }

    #[test]
    fn cholupdate_matches_refactorisation_both_ways() {
        let n = 6;
        let p = spd(n, 3);
        let l = cholesky_psd(&p, n).unwrap();
        let v: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 + 1.0).sin()).collect();
        for sign in [1.0, -1.0] {
            let mut l2 = l.clone();
            let mut w = v.clone();
            cholupdate(&mut l2, n, &mut w, sign).unwrap();
            let mut p2 = p.clone();
            for i in 0..n {
                for j in 0..n {
                    p2[i + j * n] += sign * v[i] * v[j];
                }
            }
            let want = cholesky_psd(&p2, n).unwrap();
            for k in 0..n * n {
                assert_relative_eq!(l2[k], want[k], epsilon = 1e-12);
            }
        }
    }

    #[test]
    fn downdate_that_loses_definiteness_is_reported() {
        let n = 3;
        let l = vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];
        let mut l2 = l.clone();
        let mut v = vec![0.0, 2.0, 0.0];
        assert_eq!(
            cholupdate(&mut l2, n, &mut v, -1.0),
            Err(DowndateFailed { column: 1 })
        );
    }

    #[test]
    fn qr_lower_is_the_cholesky_factor_of_the_gram_matrix() {
        let (rows, n) = (9, 4);
        let a: Vec<f64> = (0..rows * n)
            .map(|k| ((k * 7 + 3) % 11) as f64 - 5.0)
            .collect();
        let mut gram = vec![0.0; n * n];
        for i in 0..n {
            for j in 0..n {
                gram[i + j * n] = (0..rows).map(|r| a[r + i * rows] * a[r + j * rows]).sum();
            }
        }
        let mut work = a.clone();
        let mut l = vec![0.0; n * n];
        qr_lower(&mut work, rows, n, 0, &mut l);
        let want = cholesky_psd(&gram, n).unwrap();
        for k in 0..n * n {
            assert_relative_eq!(l[k], want[k], epsilon = 1e-10, max_relative = 1e-12);
        }
    }

    #[test]
    fn qr_lower_skips_the_zeros_of_a_triangular_tail() {
        let (dense, n) = (8, 4);
        let rows = dense + n;
        let mut a: Vec<f64> = (0..rows * n)
            .map(|k| ((k * 5 + 1) % 13) as f64 - 6.0)
            .collect();
        for c in 0..n {
            for j in 0..n {
                if j > c {
                    a[dense + j + c * rows] = 0.0; // upper-triangular tail
                }
            }
        }
        let (mut w0, mut w1) = (a.clone(), a.clone());
        let (mut l0, mut l1) = (vec![0.0; n * n], vec![0.0; n * n]);
        qr_lower(&mut w0, rows, n, 0, &mut l0);
        qr_lower(&mut w1, rows, n, n, &mut l1);
        for k in 0..n * n {
            assert_relative_eq!(l0[k], l1[k], epsilon = 1e-12, max_relative = 1e-12);
        }
    }

    #[test]
    fn triangular_solves_invert_the_factor() {
        let n = 5;
        let l = cholesky_psd(&spd(n, 9), n).unwrap();
        let x: Vec<f64> = (0..n).map(|i| i as f64 - 2.0).collect();
        let mut b = vec![0.0; n];
        for i in 0..n {
            b[i] = (0..=i).map(|k| l[i + k * n] * x[k]).sum();
        }
        solve_lower(&l, n, &mut b);
        for i in 0..n {
            assert_relative_eq!(b[i], x[i], epsilon = 1e-12);
        }
        for i in 0..n {
            b[i] = (i..n).map(|k| l[k + i * n] * x[k]).sum();
        }
        solve_lower_transpose(&l, n, &mut b);
        for i in 0..n {
            assert_relative_eq!(b[i], x[i], epsilon = 1e-12);
        }
    }

    #[test]
    fn nearest_spd_repairs_an_indefinite_matrix() {
        let n = 2;
        let p = vec![1.0, 2.0, 2.0, 1.0]; // eigenvalues 3, −1
        let l = nearest_spd_factor(&p, n, 1e-9);
        let back = outer_lower(&l, n);
        // projection: eigenvalue −1 → ~0, so P ≈ 1.5·[1 1; 1 1]
        assert_relative_eq!(back[0], 1.5, epsilon = 1e-6);
        assert_relative_eq!(back[1], 1.5, epsilon = 1e-6);
        assert!(l[0] > 0.0 && l[3] > 0.0);
    }
}
