//! MATLAB `mapminmax` normalisation of inputs and outputs to [−1, 1].

/// Per-feature affine map `a = (x − x_min)·g − 1`, `g = 2 / (x_max − x_min)` (`g = 1` when the
/// training range is empty, as in `mapminmax`), and its inverse for outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct MapMinMax {
    /// Training minimum per feature (physical units).
    pub min: Vec<f64>,
    /// Training maximum per feature (physical units).
    pub max: Vec<f64>,
    gain: Vec<f64>,
}

impl MapMinMax {
    /// From the training ranges; the caller has checked equal lengths and finite values.
    pub fn new(min: Vec<f64>, max: Vec<f64>) -> Self {
        let gain = min
            .iter()
            .zip(&max)
            .map(|(lo, hi)| {
                let range = hi - lo;
                if range > 0.0 && range.is_finite() {
                    2.0 / range
                } else {
                    1.0
                }
            })
            .collect();
        Self { min, max, gain }
    }

    /// The identity map for `n` features (a network stored without normalisation).
    pub fn identity(n: usize) -> Self {
        Self {
            min: vec![-1.0; n],
            max: vec![1.0; n],
            gain: vec![1.0; n],
        }
    }

    /// Number of features.
    pub fn len(&self) -> usize {
        self.min.len()
    }

    /// Per-feature gain `g` (`2 / (x_max − x_min)`, or 1 for an empty range).
    pub fn gain(&self) -> &[f64] {
        &self.gain
    }

    /// True when there are no features.
    pub fn is_empty(&self) -> bool {
        self.min.is_empty()
    }

    /// Physical → normalised, `x.len() == out.len() == self.len()`.
    #[inline(always)]
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for (((o, &v), &lo), &g) in out.iter_mut().zip(x).zip(&self.min).zip(&self.gain) {
            *o = (v - lo) * g - 1.0;
        }
    }

    /// Normalised → physical.
    #[inline(always)]
    pub fn reverse(&self, a: &[f64], out: &mut [f64]) {
        for (((o, &v), &lo), &g) in out.iter_mut().zip(a).zip(&self.min).zip(&self.gain) {
            *o = (v + 1.0) / g + lo;
        }
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // saturation and range ends are exact by construction
mod tests {
    use super::*;

    #[test]
    fn maps_range_to_unit_interval_and_back() {
        let m = MapMinMax::new(vec![0.0, -3.0, 5.0], vec![10.0, 1.0, 5.0]);
        let mut a = [0.0; 3];
        m.apply(&[0.0, 1.0, 5.0], &mut a);
        assert_eq!(a, [-1.0, 1.0, -1.0]);
        m.apply(&[10.0, -3.0, 7.0], &mut a);
        assert_eq!(a, [1.0, -1.0, 1.0]);
        let mut back = [0.0; 3];
        m.reverse(&a, &mut back);
        assert_eq!(back, [10.0, -3.0, 7.0]);
    }
}
