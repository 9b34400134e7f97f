//! Linear K/B calibration: the statistics of the readings taken in each
//! standard, and the line through them.
//!
//! A probe with a user calibration block reports final = K x raw + B. The
//! vendor's calibrator sheets set K = 1, B = 0, take several readings in
//! each of up to four standards, show each standard's mean, standard
//! deviation and coefficient of variation, and fit a line through
//! (mean reading, standard): its slope is the new K, its intercept the new
//! B. With one standard there is no slope to fit: K stays 1 and B is the
//! offset that brings the reading onto the standard.

use std::fmt;

/// Mean, sample standard deviation and coefficient of variation of readings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReadingStats {
    /// How many readings.
    pub count: usize,
    /// Their mean.
    pub mean: f64,
    /// Their sample standard deviation (n - 1); 0 for one reading.
    pub sd: f64,
    /// SD / |mean| in percent; `None` when the mean is 0 (no scale to relate it to).
    pub cv_percent: Option<f64>,
}

/// The statistics of `readings`; `None` when there is none or one is not finite.
pub fn stats(readings: &[f64]) -> Option<ReadingStats> {
    if readings.is_empty() || readings.iter().any(|r| !r.is_finite()) {
        return None;
    }
    let n = readings.len() as f64;
    let mean = readings.iter().sum::<f64>() / n;
    let sd = if readings.len() > 1 {
        (readings.iter().map(|r| (r - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    } else {
        0.0
    };
    let cv_percent = (mean != 0.0).then(|| 100.0 * sd / mean.abs());
    Some(ReadingStats { count: readings.len(), mean, sd, cv_percent })
}

/// The trend of readings taken at equal intervals: the least-squares slope
/// per reading; `None` for fewer than two readings or one not finite.
pub fn trend(readings: &[f64]) -> Option<f64> {
    if readings.len() < 2 || readings.iter().any(|r| !r.is_finite()) {
        return None;
    }
    let n = readings.len() as f64;
    let x_mean = (n - 1.0) / 2.0;
    let y_mean = readings.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, y) in readings.iter().enumerate() {
        let dx = i as f64 - x_mean;
        sxy += dx * (y - y_mean);
        sxx += dx * dx;
    }
    Some(sxy / sxx)
}

/// One standard: its known value and the mean reading the probe gave in it
/// with K = 1 and B = 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandardReading {
    /// The standard's value, in the calibrated field's unit.
    pub standard: f64,
    /// The mean raw reading in it.
    pub reading: f64,
}

/// The calibration line: standard = K x reading + B.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    /// Slope K.
    pub k: f64,
    /// Offset B.
    pub b: f64,
    /// Per standard, in order: standard - (K x reading + B).
    pub residuals: Vec<f64>,
    /// Coefficient of determination of the line; `None` for one standard
    /// (nothing to fit) or standards that are all equal.
    pub r_squared: Option<f64>,
}

/// Why no line can be fitted.
#[derive(Debug, Clone, PartialEq)]
pub enum FitError {
    /// No standard at all.
    NoStandards,
    /// A standard or a reading is not a finite number.
    NotFinite,
    /// Two or more standards, but the probe read the same in each: no slope.
    SameReadings,
    /// Two or more standards of the same value: no slope either.
    SameStandards,
}

impl fmt::Display for FitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FitError::NoStandards => "no standard was measured",
            FitError::NotFinite => "a standard or a reading is not a finite number",
            FitError::SameReadings => "the probe read the same value in every standard, so no slope can be fitted",
            FitError::SameStandards => "every standard has the same value, so no slope can be fitted",
        })
    }
}

impl std::error::Error for FitError {}

/// The line through `points`: an offset for one standard (K = 1), the
/// least-squares line for two or more.
pub fn fit(points: &[StandardReading]) -> Result<LinearFit, FitError> {
    if points.is_empty() {
        return Err(FitError::NoStandards);
    }
    if points.iter().any(|p| !p.standard.is_finite() || !p.reading.is_finite()) {
        return Err(FitError::NotFinite);
    }
    let (k, b) = if let [one] = points {
        (1.0, one.standard - one.reading)
    } else {
        let n = points.len() as f64;
        let x_mean = points.iter().map(|p| p.reading).sum::<f64>() / n;
        let y_mean = points.iter().map(|p| p.standard).sum::<f64>() / n;
        let sxx: f64 = points.iter().map(|p| (p.reading - x_mean).powi(2)).sum();
        let syy: f64 = points.iter().map(|p| (p.standard - y_mean).powi(2)).sum();
        let sxy: f64 = points.iter().map(|p| (p.reading - x_mean) * (p.standard - y_mean)).sum();
        if sxx == 0.0 {
            return Err(FitError::SameReadings);
        }
        if syy == 0.0 {
            return Err(FitError::SameStandards);
        }
        let k = sxy / sxx;
        (k, y_mean - k * x_mean)
    };
    if !k.is_finite() || !b.is_finite() {
        return Err(FitError::NotFinite);
    }
    let residuals: Vec<f64> = points.iter().map(|p| p.standard - (k * p.reading + b)).collect();
    let r_squared = (points.len() > 1).then(|| {
        let y_mean = points.iter().map(|p| p.standard).sum::<f64>() / points.len() as f64;
        let total: f64 = points.iter().map(|p| (p.standard - y_mean).powi(2)).sum();
        let residual: f64 = residuals.iter().map(|r| r * r).sum();
        1.0 - residual / total
    });
    Ok(LinearFit { k, b, residuals, r_squared })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    fn points(pairs: &[(f64, f64)]) -> Vec<StandardReading> {
        pairs.iter().map(|&(reading, standard)| StandardReading { standard, reading }).collect()
    }

    #[test]
    fn stats_by_hand() {
        // Mean 2.5; deviations ±1.5, ±0.5: SD = sqrt(5 / 3); CV = SD / 2.5.
        let s = stats(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!(s.count, 4);
        assert!(close(s.mean, 2.5));
        assert!(close(s.sd, (5.0f64 / 3.0).sqrt()));
        assert!(close(s.cv_percent.unwrap(), 100.0 * (5.0f64 / 3.0).sqrt() / 2.5));
        let one = stats(&[-7.0]).unwrap();
        assert_eq!((one.mean, one.sd), (-7.0, 0.0));
        assert_eq!(one.cv_percent, Some(0.0));
        assert_eq!(stats(&[-1.0, 1.0]).unwrap().cv_percent, None, "no CV around a zero mean");
        assert_eq!(stats(&[]), None);
        assert_eq!(stats(&[1.0, f64::NAN]), None);
    }

    #[test]
    fn trend_by_hand() {
        assert!(close(trend(&[1.0, 3.0, 5.0]).unwrap(), 2.0));
        // x = 0, 1, 2, 3 (mean 1.5); y = 2, 2, 4, 4: Sxy = 4, Sxx = 5.
        assert!(close(trend(&[2.0, 2.0, 4.0, 4.0]).unwrap(), 0.8));
        assert_eq!(trend(&[1.0]), None);
    }

    #[test]
    fn one_standard_is_an_offset() {
        let f = fit(&points(&[(9.75, 10.0)])).unwrap();
        assert_eq!((f.k, f.b), (1.0, 0.25));
        assert_eq!(f.residuals, vec![0.0]);
        assert_eq!(f.r_squared, None);
    }

    #[test]
    fn two_standards_give_the_line_through_both() {
        // Through (1, 3) and (3, 7): K = 2, B = 1.
        let f = fit(&points(&[(1.0, 3.0), (3.0, 7.0)])).unwrap();
        assert!(close(f.k, 2.0) && close(f.b, 1.0), "{f:?}");
        assert!(f.residuals.iter().all(|r| r.abs() < 1e-12));
        assert!(close(f.r_squared.unwrap(), 1.0));
    }

    #[test]
    fn three_standards_give_the_least_squares_line() {
        // (0, 1), (1, 3), (2, 4): mean reading 1, mean standard 8/3,
        // Sxy = 3, Sxx = 2: K = 1.5, B = 8/3 - 1.5 = 7/6. Residuals -1/6,
        // 1/3, -1/6: SSres = 1/6; SStot = 14/3; R² = 1 - (1/6)/(14/3) = 27/28.
        let f = fit(&points(&[(0.0, 1.0), (1.0, 3.0), (2.0, 4.0)])).unwrap();
        assert!(close(f.k, 1.5), "{f:?}");
        assert!(close(f.b, 7.0 / 6.0), "{f:?}");
        for (got, want) in f.residuals.iter().zip([-1.0 / 6.0, 1.0 / 3.0, -1.0 / 6.0]) {
            assert!(close(*got, want), "{f:?}");
        }
        assert!(close(f.r_squared.unwrap(), 27.0 / 28.0), "{f:?}");
    }

    #[test]
    fn degenerate_standards_are_refused() {
        assert_eq!(fit(&[]), Err(FitError::NoStandards));
        assert_eq!(fit(&points(&[(2.0, 1.0), (2.0, 5.0)])), Err(FitError::SameReadings));
        assert_eq!(fit(&points(&[(1.0, 4.0), (2.0, 4.0)])), Err(FitError::SameStandards));
        assert_eq!(fit(&points(&[(1.0, f64::INFINITY)])), Err(FitError::NotFinite));
        assert!(!FitError::SameReadings.to_string().is_empty());
    }
}
