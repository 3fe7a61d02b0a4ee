//! Wrench-feasible and static workspace: the capacity margin of a pose by hyperplane shifting.
//!
//! The tensions `f_min ≤ f ≤ f_max` generate the available wrench set, the zonotope
//! `Z = {Aᵀ·f}`; a pose holds the wrench `w` when `−w ∈ Z`. Every facet of `Z` is normal to
//! `n − 1` columns of `Aᵀ` (Bouchard, Gosselin and Moore 2010, the hyperplane shifting method),
//! and the support of `Z` in a direction `c` is `h(c) = Σᵢ max(f_minᵢ·c·aᵢ, f_maxᵢ·c·aᵢ)`.
//! The **capacity margin** (Guay, Cardou, Ruiz and Caro 2014) is the signed distance from the
//! required wrench set to the nearest facet: with the weight `w_g`, a required wrench box
//! `w_c ± δ` and the facet normals `c`,
//!
//! ```text
//! s = min_c (h(c) + c·(w_g + w_c) − Σₖ |cₖ|·δₖ) / ‖c‖
//! ```
//!
//! `s ≥ 0` is exact membership of the wrench-feasible workspace (every wrench of the box can
//! be held within the bounds); `s` is then the radius of the largest wrench ball that can be
//! added. With no box (`δ = 0`, `w_c = 0`) it is the static workspace, and `s` is how far the
//! weight is from the nearest wrench the cables can no longer hold.
//!
//! The facet normals come cheaply from one Gauss–Jordan elimination with complete pivoting:
//! with `M = B⁻¹` for a basis `B` of `n` columns, `T = M·Aᵀ` has unit columns on the basis and
//! `r = m − n` other columns, and a normal `c = Mᵀ·d` orthogonal to `n − 1` columns has a `d`
//! supported on the `q + 1` basis coordinates its set leaves out (`q` of the set being
//! non-basis columns): `d` is a generalised cross product of size `q + 1 ≤ n`, `c·aᵢ = d·tᵢ`
//! and `‖c‖² = dᵀ·(M·Mᵀ)·d` touch only those coordinates. All in fixed-size stack buffers.
//!
//! Moments enter the distance divided by a characteristic length (`moment_length`), so that
//! the margin is a force (N) when it is set to the platform's size; 1 m by default.

use super::kinematics::{inverse_kinematics, CableGeometry, Pose};
use super::robot::{Motion, Robot, MAX_CABLES};
use crate::error::{check, CableError, Result};

/// Largest pivot (relative to the largest `|Aᵀ|` entry) below which the structure matrix
/// counts as rank deficient: the pose is degenerate.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// The wrench set a pose must hold: the platform's weight (if `gravity`) plus every wrench of
/// the box `center ± half_width` (per component, the robot's `n` entries).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Requirement {
    /// Add the platform's weight.
    pub gravity: bool,
    /// Centre of the required external wrench box (N, N·m).
    pub center: [f64; 6],
    /// Half widths of the box, each `≥ 0` (N, N·m).
    pub half_width: [f64; 6],
    /// Moments count in the distance as `moment / moment_length` (m, `> 0`).
    pub moment_length: f64,
    /// Where the margin must be exact (see [`Margins`]).
    pub margins: Margins,
}

/// Where [`capacity_margin`] measures the margin exactly.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Margins {
    /// At every pose: every facet pair is examined.
    #[default]
    Everywhere,
    /// Inside the workspace only: the scan stops at the first facet the required wrench set
    /// crosses, so an outside pose's `margin` is that facet's (negative) distance, an upper
    /// bound of the exact margin, and its `weakest` that facet's direction. Membership
    /// (`feasible`) and the margins of inside poses are exact, as with `Everywhere`.
    Inside,
}

impl Margins {
    /// From its name (`"everywhere"`, `"inside"`).
    pub fn from_name(name: &str) -> Result<Self> {
        match name {
            "everywhere" => Ok(Self::Everywhere),
            "inside" => Ok(Self::Inside),
            other => Err(CableError::InvalidOption {
                name: "margins".into(),
                value: other.into(),
                allowed: "everywhere, inside".into(),
            }),
        }
    }
}

impl Default for Requirement {
    /// The static workspace: the weight only, moments in N·m as they are.
    fn default() -> Self {
        Self {
            gravity: true,
            center: [0.0; 6],
            half_width: [0.0; 6],
            moment_length: 1.0,
            margins: Margins::Everywhere,
        }
    }
}

impl Requirement {
    /// Checks the values for a robot of `n` degrees of freedom.
    pub fn validate(&self, n: usize) -> Result<()> {
        check::all_finite("wrench centre", &self.center[..n], n)?;
        check::all_finite("wrench half widths", &self.half_width[..n], n)?;
        if let Some((k, &v)) = self.half_width[..n]
            .iter()
            .enumerate()
            .find(|(_, v)| **v < 0.0)
        {
            return Err(CableError::InvalidParameter {
                name: format!("wrench half widths[{k}]"),
                value: v,
                requirement: ">= 0",
            });
        }
        if !(self.moment_length.is_finite() && self.moment_length > 0.0) {
            return Err(CableError::InvalidParameter {
                name: "moment_length".into(),
                value: self.moment_length,
                requirement: "finite and > 0",
            });
        }
        Ok(())
    }
}

/// The capacity of one pose.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Capacity {
    /// Capacity margin (N with moments divided by the moment length): `≥ 0` inside the
    /// workspace, the distance to the nearest facet of the available wrench set; `0` at a
    /// degenerate pose.
    pub margin: f64,
    /// Every required wrench can be held within the bounds (`margin ≥ 0`, not degenerate).
    pub feasible: bool,
    /// `Aᵀ` is rank deficient (the cables cannot span the wrench space at this pose).
    pub degenerate: bool,
    /// Facet normals examined (`C(m, n − 1)` at a regular pose).
    pub facets: usize,
    /// The external wrench direction the pose resists least (N, N·m; unit in the margin's
    /// norm, the first `n` entries): adding `margin · weakest` to the required wrench reaches
    /// the boundary of the available wrench set. Zero at a degenerate pose.
    pub weakest: [f64; 6],
    /// The `n − 1` cables (bit `i` for cable `i`) whose columns the facet behind `margin` is
    /// parallel to: the other cables sit at a tension limit on it. Zero at a degenerate pose.
    pub facet_cables: u32,
}

/// First `k`-combination of `0..`.
fn first_combination(idx: &mut [usize], k: usize) {
    for (i, v) in idx[..k].iter_mut().enumerate() {
        *v = i;
    }
}

/// Next `k`-combination of `0..n` in lexicographic order; `false` after the last.
fn next_combination(idx: &mut [usize], k: usize, n: usize) -> bool {
    let mut i = k;
    while i > 0 {
        i -= 1;
        if idx[i] < n - k + i {
            idx[i] += 1;
            for j in i + 1..k {
                idx[j] = idx[j - 1] + 1;
            }
            return true;
        }
    }
    false
}

/// Determinant of the leading `q × q` block of `a` (partial pivoting; `a` is overwritten).
fn determinant(a: &mut [[f64; 6]; 6], q: usize) -> f64 {
    let mut det = 1.0;
    for k in 0..q {
        let p = (k..q)
            .max_by(|&x, &y| a[x][k].abs().total_cmp(&a[y][k].abs()))
            .unwrap_or(k);
        if a[p][k] == 0.0 {
            return 0.0;
        }
        if p != k {
            a.swap(p, k);
            det = -det;
        }
        det *= a[k][k];
        for r in k + 1..q {
            let f = a[r][k] / a[k][k];
            for c in k + 1..q {
                a[r][c] -= f * a[k][c];
            }
        }
    }
    det
}

/// The generalised cross product of the `q` rows of `k` (`q × (q + 1)`): the vector of signed
/// maximal minors, orthogonal to every row.
fn cross_rows(k: &[[f64; 6]; 6], q: usize, d: &mut [f64; 6]) {
    match q {
        0 => d[0] = 1.0,
        1 => {
            d[0] = k[0][1];
            d[1] = -k[0][0];
        }
        2 => {
            d[0] = k[0][1] * k[1][2] - k[0][2] * k[1][1];
            d[1] = k[0][2] * k[1][0] - k[0][0] * k[1][2];
            d[2] = k[0][0] * k[1][1] - k[0][1] * k[1][0];
        }
        _ => {
            for (b, db) in d[..=q].iter_mut().enumerate() {
                let mut minor = [[0.0; 6]; 6];
                for r in 0..q {
                    let mut c2 = 0;
                    for c in 0..=q {
                        if c != b {
                            minor[r][c2] = k[r][c];
                            c2 += 1;
                        }
                    }
                }
                let sign = if (b + q).is_multiple_of(2) { 1.0 } else { -1.0 };
                *db = sign * determinant(&mut minor, q);
            }
        }
    }
}

/// A facet normal's `d` counts only when `‖d‖² > SINE_TOLERANCE · Π‖rows‖²` (its columns are
/// not dependent to within a sine of 1e-12; a dependent set has no facet).
const SINE_TOLERANCE: f64 = 1e-24;

/// The eliminated structure matrix of one pose. Coordinate arrays are 8 wide and indexed
/// with `& 7`, which lets the compiler drop the bounds checks in the facet loop.
///
/// With the middle tensions `mid = (f_min + f_max)/2` and half ranges `rad = (f_max − f_min)/2`,
/// `max(f_minᵢ·pᵢ, f_maxᵢ·pᵢ) = midᵢ·pᵢ + radᵢ·|pᵢ|`, so the two facets `±c` of a pair share
/// the spread `Σᵢ radᵢ·|c·aᵢ|` and their distances are
/// `(Σᵢ radᵢ·|c·aᵢ| − Σₖ |cₖ|·δₖ ± c·g) / ‖c‖` with `g = Aᵀ·mid + w`: the nearer one is
/// `(spread − width − |c·g|) / ‖c‖`, and `c·g = d·(M·g)` in basis coordinates.
struct Kernel {
    /// Non-basis columns.
    r: usize,
    /// `T`'s non-basis columns, column-major.
    tx: [[f64; 8]; MAX_CABLES],
    /// Half ranges of the non-basis cables.
    rad_x: [f64; MAX_CABLES],
    /// Half ranges of the basis cables, by coordinate.
    rad_b: [f64; 8],
    /// `M·(Aᵀ·mid + w)`.
    g: [f64; 8],
    /// `M·Mᵀ`.
    h: [[f64; 8]; 8],
    /// `M = B⁻¹`.
    mm: [[f64; 8]; 8],
    /// Required box half widths (scaled).
    delta: [f64; 8],
    boxed: bool,
    /// The cable of each basis coordinate and of each non-basis column.
    col_b: [usize; 8],
    col_x: [usize; MAX_CABLES],
}

/// The nearest facet so far.
struct Best {
    /// Numerator and `‖c‖²` of the nearest facet's distance `num / ‖c‖`.
    num: f64,
    norm2: f64,
    d: [f64; 6],
    f: [usize; 6],
    len: usize,
    /// The cables' wrench leaves through `+c` (else `−c`).
    up: bool,
    /// The non-basis columns the nearest facet is parallel to (bit set).
    skip: u32,
    facets: usize,
}

impl Kernel {
    /// The facet pair `±c` with `c = Mᵀ·d`, `d` on the free coordinates `f`; the non-basis
    /// columns in `skip` (a bit set) are orthogonal to it.
    #[inline(always)]
    fn facet<const L: usize>(&self, d: [f64; L], f: [usize; L], skip: u32, best: &mut Best) {
        let (mut spread, mut along, mut norm2) = (0.0, 0.0, 0.0);
        for a in 0..L {
            let fa = f[a] & 7;
            spread += self.rad_b[fa] * d[a].abs();
            along += d[a] * self.g[fa];
            // ‖c‖² = dᵀ·H·d over the upper triangle
            let ha = &self.h[fa];
            let mut row = ha[fa] * d[a];
            for b in 0..a {
                row += 2.0 * ha[f[b] & 7] * d[b];
            }
            norm2 += d[a] * row;
        }
        for x in 0..self.r {
            if skip & (1 << x) == 0 {
                let x = x & (MAX_CABLES - 1);
                let tx = &self.tx[x];
                let mut p = 0.0;
                for a in 0..L {
                    p += d[a] * tx[f[a] & 7];
                }
                spread += self.rad_x[x] * p.abs();
            }
        }
        let width = if self.boxed {
            let mut c = [0.0; 8];
            for a in 0..L {
                let row = &self.mm[f[a] & 7];
                for j in 0..8 {
                    c[j] += d[a] * row[j];
                }
            }
            (0..8).map(|j| c[j].abs() * self.delta[j]).sum()
        } else {
            0.0
        };
        best.facets += 1;
        let num = spread - width - along.abs();
        // num/‖c‖ < best, compared as num·|num|·best‖c‖² < best_num·|best_num|·‖c‖² (no square
        // root), or with the roots where those products are not finite
        let (lhs, rhs) = (
            num * num.abs() * best.norm2,
            best.num * best.num.abs() * norm2,
        );
        let diff = lhs - rhs;
        let nearer = if diff.is_finite() {
            diff < 0.0
        } else {
            num * best.norm2.sqrt() < best.num * norm2.sqrt()
        };
        if nearer & (norm2 > 0.0) {
            (best.num, best.norm2) = (num, norm2);
            best.d[..L].copy_from_slice(&d);
            best.f[..L].copy_from_slice(&f);
            best.len = L;
            best.up = along <= 0.0;
            best.skip = skip;
        }
    }
}

/// Capacity margin of the structure matrix `at` (`n × m`, row-major) for tensions within
/// `f_min ≤ f ≤ f_max` against the external wrench `weight` (gravity, or zeros) plus the
/// requirement's box. No allocation.
pub fn capacity_margin(
    at: &[f64],
    n: usize,
    m: usize,
    f_min: &[f64],
    f_max: &[f64],
    weight: &[f64],
    req: &Requirement,
) -> Result<Capacity> {
    if !(1..=6).contains(&n) || m < n || m > MAX_CABLES || at.len() != n * m {
        return Err(CableError::Shape {
            what: "structure matrix".into(),
            expected: format!("n x m with 1 <= n <= 6, n <= m <= {MAX_CABLES}"),
            got: format!("{} values for n = {n}, m = {m}", at.len()),
        });
    }
    for (what, v, len) in [
        ("f_min", f_min, m),
        ("f_max", f_max, m),
        ("wrench", weight, n),
    ] {
        if v.len() != len {
            return Err(CableError::Shape {
                what: what.into(),
                expected: format!("{len} values"),
                got: format!("{}", v.len()),
            });
        }
    }
    margin_checked(n, (at, m, f_min, f_max, weight, req))
}

/// [`capacity_margin`] of checked arguments.
fn margin_checked(n: usize, args: MarginArgs<'_>) -> Result<Capacity> {
    #[cfg(target_arch = "x86_64")]
    if crate::lanes::cpu_has_avx2_fma() {
        #[allow(unsafe_code)]
        // SAFETY: the CPU reported AVX2 and FMA, all `margin_avx2` requires
        return unsafe { margin_avx2(n, args) };
    }
    margin(n, args)
}

/// [`margin`] compiled for 256-bit lanes (the same operations in the same order).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn margin_avx2(n: usize, args: MarginArgs<'_>) -> Result<Capacity> {
    margin(n, args)
}

/// [`capacity_margin`] of checked arguments.
#[inline(always)]
fn margin(n: usize, args: MarginArgs<'_>) -> Result<Capacity> {
    let (_, m, _, _, _, req) = args;
    let row_scale = |r: usize| row_scale(n, req.moment_length, r);
    let mut k = Kernel {
        r: 0,
        tx: [[0.0; 8]; MAX_CABLES],
        rad_x: [0.0; MAX_CABLES],
        rad_b: [0.0; 8],
        g: [0.0; 8],
        h: [[0.0; 8]; 8],
        mm: [[0.0; 8]; 8],
        delta: [0.0; 8],
        boxed: false,
        col_b: [0; 8],
        col_x: [0; MAX_CABLES],
    };
    let regular = match (n, m <= 8) {
        (1, true) => eliminate::<1, 8>(args, &mut k),
        (2, true) => eliminate::<2, 8>(args, &mut k),
        (3, true) => eliminate::<3, 8>(args, &mut k),
        (4, true) => eliminate::<4, 8>(args, &mut k),
        (5, true) => eliminate::<5, 8>(args, &mut k),
        (6, true) => eliminate::<6, 8>(args, &mut k),
        (1, false) => eliminate::<1, MAX_CABLES>(args, &mut k),
        (2, false) => eliminate::<2, MAX_CABLES>(args, &mut k),
        (3, false) => eliminate::<3, MAX_CABLES>(args, &mut k),
        (4, false) => eliminate::<4, MAX_CABLES>(args, &mut k),
        (5, false) => eliminate::<5, MAX_CABLES>(args, &mut k),
        _ => eliminate::<6, MAX_CABLES>(args, &mut k),
    };
    if !regular {
        return Ok(Capacity {
            margin: 0.0,
            feasible: false,
            degenerate: true,
            facets: 0,
            weakest: [0.0; 6],
            facet_cables: 0,
        });
    }
    let mm = &k.mm;
    let mut best = Best {
        num: f64::INFINITY,
        norm2: 1.0,
        d: [0.0; 6],
        f: [0; 6],
        len: 0,
        up: true,
        skip: 0,
        facets: 0,
    };
    let r = k.r;
    // an outside pose's scan may stop at the first crossed facet
    let stop = req.margins == Margins::Inside;
    'scan: {
        // q = 0: the n − 1 other basis columns; d = e_f.
        for f in 0..n {
            k.facet([1.0], [f], 0, &mut best);
        }
        if stop && best.num < 0.0 {
            break 'scan;
        }
        // q = 1: one non-basis column x and two free coordinates.
        for x in (0..r).filter(|_| n >= 2) {
            let tx = k.tx[x];
            for f0 in 0..n {
                for f1 in f0 + 1..n {
                    let d = [tx[f1], -tx[f0]];
                    let size = tx[f0] * tx[f0] + tx[f1] * tx[f1];
                    if d[0] * d[0] + d[1] * d[1] > SINE_TOLERANCE * size {
                        k.facet(d, [f0, f1], 1 << x, &mut best);
                    }
                }
            }
            if stop && best.num < 0.0 {
                break 'scan;
            }
        }
        // q = 2: two non-basis columns and three free coordinates.
        if n >= 3 {
            for x in 0..r {
                for y in x + 1..r {
                    let (a, b) = (k.tx[x], k.tx[y]);
                    for f0 in 0..n {
                        for f1 in f0 + 1..n {
                            for f2 in f1 + 1..n {
                                let (a, b) = ([a[f0], a[f1], a[f2]], [b[f0], b[f1], b[f2]]);
                                let d = [
                                    a[1] * b[2] - a[2] * b[1],
                                    a[2] * b[0] - a[0] * b[2],
                                    a[0] * b[1] - a[1] * b[0],
                                ];
                                let size = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
                                    * (b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
                                if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > SINE_TOLERANCE * size {
                                    k.facet(d, [f0, f1, f2], (1 << x) | (1 << y), &mut best);
                                }
                            }
                        }
                    }
                    if stop && best.num < 0.0 {
                        break 'scan;
                    }
                }
            }
        }
        // q ≥ 3 (more than two redundant cables): signed maximal minors.
        let mut qset = [0usize; 6];
        let mut fset = [0usize; 6];
        for q in 3..=r.min(n - 1) {
            first_combination(&mut qset, q);
            loop {
                first_combination(&mut fset, q + 1);
                loop {
                    let mut rows = [[0.0; 6]; 6];
                    let mut size = 1.0;
                    let mut skip = 0u32;
                    for a in 0..q {
                        let x = qset[a];
                        skip |= 1 << x;
                        let mut norm2 = 0.0;
                        for b in 0..=q {
                            rows[a][b] = k.tx[x][fset[b]];
                            norm2 += rows[a][b] * rows[a][b];
                        }
                        size *= norm2;
                    }
                    let mut d = [0.0; 6];
                    cross_rows(&rows, q, &mut d);
                    if d[..=q].iter().map(|v| v * v).sum::<f64>() > SINE_TOLERANCE * size {
                        match q {
                            3 => k.facet(
                                [d[0], d[1], d[2], d[3]],
                                [fset[0], fset[1], fset[2], fset[3]],
                                skip,
                                &mut best,
                            ),
                            4 => k.facet(
                                [d[0], d[1], d[2], d[3], d[4]],
                                [fset[0], fset[1], fset[2], fset[3], fset[4]],
                                skip,
                                &mut best,
                            ),
                            _ => k.facet(d, fset, skip, &mut best),
                        }
                    }
                    if !next_combination(&mut fset, q + 1, n) {
                        break;
                    }
                }
                if stop && best.num < 0.0 {
                    break 'scan;
                }
                if !next_combination(&mut qset, q, r) {
                    break;
                }
            }
        }
    }
    let margin = best.num / best.norm2.sqrt();
    // The weakest external direction: −c (the cables' wrench leaves through +c) or +c.
    let mut weakest = [0.0; 6];
    if margin.is_finite() {
        let sign = if best.up { -1.0 } else { 1.0 };
        let scale = sign / best.norm2.sqrt();
        for (j, wj) in weakest[..n].iter_mut().enumerate() {
            let c: f64 = (0..best.len).map(|b| best.d[b] * mm[best.f[b]][j]).sum();
            *wj = scale * c / row_scale(j);
        }
    }
    let facets = best.facets;
    let mut facet_cables = 0u32;
    for b in (0..n).filter(|b| !best.f[..best.len].contains(b)) {
        facet_cables |= 1 << k.col_b[b];
    }
    for x in (0..r).filter(|x| best.skip & (1 << x) != 0) {
        facet_cables |= 1 << k.col_x[x];
    }
    if !margin.is_finite() {
        return Err(CableError::NonFiniteResult {
            what: "capacity margin".into(),
            index: 0,
            value: margin,
            location: String::new(),
            hint: "the wrench or the bounds overflow",
        });
    }
    Ok(Capacity {
        margin,
        feasible: margin >= 0.0,
        degenerate: false,
        facets,
        weakest,
        facet_cables,
    })
}

/// Row `r`'s scale: moment rows are divided by the moment length (planar: row 2; spatial:
/// rows 3..6).
fn row_scale(n: usize, moment_length: f64, r: usize) -> f64 {
    let first_moment = if n == 3 { 2 } else { 3.min(n) };
    if r >= first_moment && n >= 3 {
        1.0 / moment_length
    } else {
        1.0
    }
}

/// `(Aᵀ, m, f_min, f_max, w, requirement)` of [`capacity_margin`], checked.
type MarginArgs<'a> = (
    &'a [f64],
    usize,
    &'a [f64],
    &'a [f64],
    &'a [f64],
    &'a Requirement,
);

/// The kernel of an `N × m` structure matrix (`m ≤ W` cables, padded with zeros to `W`):
/// Gauss–Jordan with complete pivoting on fixed-size rows, into `out` (zeroed); `false` at a
/// rank-deficient pose.
#[inline(always)]
fn eliminate<const N: usize, const W: usize>(
    (at, m, f_min, f_max, weight, req): MarginArgs<'_>,
    out: &mut Kernel,
) -> bool {
    let mut t = [[0.0; W]; N];
    let mut u = [0.0; N];
    // (rows padded to 8 lanes like `t`'s: the pivot's row swap then moves whole aligned
    // vectors; 48-byte rows were swapped through a stack copy whose overlapping 32-byte
    // halves defeated store forwarding, 8 % of the kernel)
    let mut mm = [[0.0; 8]; N];
    let mut delta = [0.0; N];
    let mut largest: f64 = 0.0;
    for r in 0..N {
        let s = row_scale(N, req.moment_length, r);
        for j in 0..m {
            t[r][j] = at[r * m + j] * s;
            largest = largest.max(t[r][j].abs());
        }
        u[r] = (weight[r] + req.center[r]) * s;
        delta[r] = req.half_width[r] * s;
        mm[r][r] = 1.0;
    }
    // Gauss–Jordan with complete pivoting: `basis[k]` is the column made the unit vector e_k
    // (exactly: its other entries are set to zero, so the remaining rows never pick it again;
    // the padding lanes are zeros and never picked either).
    let mut basis = [0usize; N];
    let mut chosen = [false; W];
    for k in 0..N {
        let mut colmax = [0.0_f64; W];
        for row in &t[k..] {
            for j in 0..W {
                let v = row[j].abs();
                colmax[j] = if v > colmax[j] { v } else { colmax[j] };
            }
        }
        // (conditional moves: a data-dependent branch here mispredicts)
        let (mut pc, mut best) = (0, -1.0);
        for (j, &v) in colmax.iter().enumerate() {
            let larger = v > best;
            pc = if larger { j } else { pc };
            best = if larger { v } else { best };
        }
        // (also catches NaN)
        if best.partial_cmp(&(RANK_TOLERANCE * largest)) != Some(std::cmp::Ordering::Greater) {
            return false;
        }
        // the row that holds the column's largest entry (the same bits as `best`)
        let pr = (k..N)
            .find(|&r| t[r][pc].abs().to_bits() == best.to_bits())
            .unwrap_or(k);
        t.swap(pr, k);
        u.swap(pr, k);
        mm.swap(pr, k);
        basis[k] = pc;
        chosen[pc] = true;
        // (the pivot column is written by lane selects, not a store into a row that is read
        // back at once as a vector: that store would stall the load)
        let inv = 1.0 / t[k][pc];
        for (j, v) in t[k].iter_mut().enumerate() {
            *v = if j == pc { 1.0 } else { *v * inv };
        }
        for v in &mut mm[k] {
            *v *= inv;
        }
        u[k] *= inv;
        let (pivot_t, pivot_m, pivot_u) = (t[k], mm[k], u[k]);
        for r in 0..N {
            if r != k {
                let f = t[r][pc];
                for j in 0..W {
                    let v = t[r][j] - f * pivot_t[j];
                    t[r][j] = if j == pc { 0.0 } else { v };
                }
                for j in 0..N {
                    mm[r][j] -= f * pivot_m[j];
                }
                u[r] -= f * pivot_u;
            }
        }
    }
    // The non-basis columns (column-major copies), the half ranges in basis order, and
    // g = M·(Aᵀ·mid + w) = T·mid + M·w.
    out.boxed = delta.iter().any(|&v| v > 0.0);
    let mut mid = [0.0; W];
    for j in 0..m {
        mid[j] = 0.5 * (f_min[j] + f_max[j]);
        if !chosen[j] {
            for row in 0..N {
                out.tx[out.r][row] = t[row][j];
            }
            out.rad_x[out.r] = 0.5 * (f_max[j] - f_min[j]);
            out.col_x[out.r] = j;
            out.r += 1;
        }
    }
    for (b, &j) in basis.iter().enumerate() {
        out.rad_b[b] = 0.5 * (f_max[j] - f_min[j]);
        out.col_b[b] = j;
        let mut g = [0.0; W];
        for i in 0..W {
            g[i] = t[b][i] * mid[i];
        }
        out.g[b] = u[b] + g.iter().sum::<f64>();
        out.delta[b] = delta[b];
        out.mm[b][..N].copy_from_slice(&mm[b][..N]);
    }
    // H = M·Mᵀ, for ‖c‖² = dᵀ·H·d.
    for a in 0..N {
        for b in 0..=a {
            let mut s = 0.0;
            for j in 0..N {
                s += mm[a][j] * mm[b][j];
            }
            out.h[a][b] = s;
            out.h[b][a] = s;
        }
    }
    true
}

/// Capacity margin of the robot at one pose (inverse kinematics, the weight if required, the
/// requirement's box), reusing `geometry` as work space.
pub fn capacity(
    robot: &Robot,
    pose: &Pose,
    req: &Requirement,
    geometry: &mut CableGeometry,
) -> Result<Capacity> {
    let (n, m) = (robot.dof(), robot.n_cables());
    inverse_kinematics(robot, pose, geometry)?;
    let mut w = [0.0; 6];
    if req.gravity {
        robot.gravity_wrench(&pose.rotation, &mut w);
    }
    let mut f_min = [0.0; MAX_CABLES];
    let mut f_max = [0.0; MAX_CABLES];
    for (i, c) in robot.cables.iter().enumerate() {
        (f_min[i], f_max[i]) = (c.f_min, c.f_max);
    }
    debug_assert!(matches!(robot.motion, Motion::Planar | Motion::Spatial));
    // (a validated robot: 1 <= n <= 6 and n <= m <= MAX_CABLES; the structure is n x m)
    debug_assert!((1..=6).contains(&n) && (n..=MAX_CABLES).contains(&m));
    let args = (
        geometry.structure(),
        m,
        &f_min[..m],
        &f_max[..m],
        &w[..n],
        req,
    );
    margin_checked(n, args)
}
