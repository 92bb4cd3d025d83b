//! The normal and Student t distributions, as far as the bootstrap's small-sample correction
//! needs them: cumulative distribution functions and their inverses. `libm` supplies `erfc`
//! and `lgamma`, so the numbers do not depend on the system's C library.

/// P(Z <= x) for a standard normal Z.
pub(crate) fn normal_cdf(x: f64) -> f64 {
    0.5 * libm::erfc(-x / std::f64::consts::SQRT_2)
}

/// The x with P(Z <= x) = p, for 0 < p < 1 (bisection on [`normal_cdf`], to 1e-12).
pub(crate) fn normal_quantile(p: f64) -> f64 {
    invert(normal_cdf, p)
}

/// P(T <= x) for Student's t with `df` degrees of freedom (df > 0), through the regularized
/// incomplete beta function: P(|T| > |x|) = I_{df / (df + x^2)}(df / 2, 1 / 2).
pub(crate) fn t_cdf(x: f64, df: f64) -> f64 {
    let tail = 0.5 * incomplete_beta(df / 2.0, 0.5, df / (df + x * x));
    if x >= 0.0 { 1.0 - tail } else { tail }
}

/// The x with P(T <= x) = p for Student's t with `df` degrees of freedom.
pub(crate) fn t_quantile(p: f64, df: f64) -> f64 {
    invert(|x| t_cdf(x, df), p)
}

/// The x with `cdf(x) = p` for an increasing `cdf`: the bracket doubles until it holds p, then
/// bisection halves it to a relative width of 1e-12.
fn invert(cdf: impl Fn(f64) -> f64, p: f64) -> f64 {
    let (mut low, mut high) = (-1.0, 1.0);
    while cdf(low) > p && low > -1e300 {
        low *= 2.0;
    }
    while cdf(high) < p && high < 1e300 {
        high *= 2.0;
    }
    for _ in 0..2000 {
        let middle = 0.5 * (low + high);
        if cdf(middle) < p {
            low = middle;
        } else {
            high = middle;
        }
        if high - low <= 1e-12 * high.abs().max(1.0) {
            break;
        }
    }
    0.5 * (low + high)
}

/// I_x(a, b), the regularized incomplete beta function, by its continued fraction (modified
/// Lentz), using the symmetry I_x(a, b) = 1 - I_{1-x}(b, a) where the fraction converges slowly.
fn incomplete_beta(a: f64, b: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if x >= 1.0 {
        return 1.0;
    }
    let log_front =
        libm::lgamma(a + b) - libm::lgamma(a) - libm::lgamma(b) + a * x.ln() + b * (1.0 - x).ln();
    if x < (a + 1.0) / (a + b + 2.0) {
        log_front.exp() * beta_fraction(a, b, x) / a
    } else {
        1.0 - log_front.exp() * beta_fraction(b, a, 1.0 - x) / b
    }
}

fn beta_fraction(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - (a + b) * x / (a + 1.0));
    let mut fraction = d;
    for m in 1..=10_000 {
        let m = f64::from(m);
        let even = m * (b - m) * x / ((a + 2.0 * m - 1.0) * (a + 2.0 * m));
        d = 1.0 / guard(1.0 + even * d);
        c = guard(1.0 + even / c);
        fraction *= d * c;
        let odd = -(a + m) * (a + b + m) * x / ((a + 2.0 * m) * (a + 2.0 * m + 1.0));
        d = 1.0 / guard(1.0 + odd * d);
        c = guard(1.0 + odd / c);
        let step = d * c;
        fraction *= step;
        if (step - 1.0).abs() < 1e-15 {
            break;
        }
    }
    fraction
}

/// A standard normal draw by Box-Muller from two uniforms, for the tests that simulate
/// experiments.
#[cfg(test)]
pub(crate) fn standard_normal(rng: &mut impl rand::RngExt) -> f64 {
    let (u, v): (f64, f64) = (rng.random(), rng.random());
    (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_values_match_tables() {
        assert!((normal_cdf(1.959_963_985) - 0.975).abs() < 1e-9);
        assert!((normal_cdf(0.0) - 0.5).abs() < 1e-15);
        assert!((normal_quantile(0.975) - 1.959_963_985).abs() < 1e-8);
        assert!((normal_quantile(0.001) + 3.090_232_306).abs() < 1e-8);
    }

    #[test]
    fn t_values_match_tables() {
        // Two-sided 95 % critical values of Student's t (any statistics table).
        for (df, critical) in [(1.0, 12.706_204_7), (2.0, 4.302_652_7), (4.0, 2.776_445_1)] {
            assert!((t_quantile(0.975, df) - critical).abs() < 1e-6, "df {df}");
            assert!((t_cdf(critical, df) - 0.975).abs() < 1e-9, "df {df}");
        }
        assert!((t_quantile(0.975, 29.0) - 2.045_229_6).abs() < 1e-6);
        assert!((t_cdf(-2.776_445_1, 4.0) - 0.025).abs() < 1e-9);
        assert!((t_quantile(0.975, 1e6) - 1.959_966).abs() < 1e-5);
    }
}
