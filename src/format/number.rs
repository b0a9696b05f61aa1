//! Numbers as text for people: labels, messages and reports print `1.6774`, not
//! `1.6773999999999998` (the nearest float64 of a value read from a file's metadata).

/// `x` as a label shows it: at most six significant digits and no trailing zeros, fixed
/// notation from 0.0001 to 999999, scientific outside (`3.33333`, `3`, `0.05`, `1.5e-7`,
/// `1.23457e9`); `0` for zero, `NaN` and `inf` as Rust writes them.
pub fn format_number(x: f64) -> String {
    if x == 0.0 {
        return "0".into();
    }
    if !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor();
    if (-4.0..6.0).contains(&magnitude) {
        let decimals = (5.0 - magnitude).max(0.0) as usize;
        without_trailing_zeros(format!("{x:.decimals$}"))
    } else {
        let text = format!("{x:.5e}");
        let (mantissa, exponent) = text.split_once('e').expect("scientific notation");
        format!(
            "{}e{exponent}",
            without_trailing_zeros(mantissa.to_string())
        )
    }
}

/// `3.500` → `3.5`, `2.000` → `2`; text without a decimal point stays.
fn without_trailing_zeros(text: String) -> String {
    match text.contains('.') {
        true => text.trim_end_matches('0').trim_end_matches('.').to_string(),
        false => text,
    }
}
