//! The shortest decimal text of an f64 that reads back to it, exactly as std prints it
//! with `{}` ([`push_display`]) and `{:e}` ([`push_lower_exp`]), from the digits of the
//! `zmij` crate (Schubfach; already in the tree through serde_json).
//!
//! Why: `points.csv` of the reference design's Δ = 3 mm sweep holds about 8 million
//! numbers (100 MB); formatted with std they took 0.50 s of the 0.81 s from the sweep's
//! end to its files (2 cores, AMD EPYC, 2026-11-27). Both produce the shortest digits that
//! round-trip, the nearest to the value among them; only the layout differs (zmij writes
//! `1.5e20` as `1.5e+20` and `5.0` as `5.0`), so the digits and the decimal exponent are
//! read from zmij's text and laid out as std does. One case is left to std: a value
//! exactly halfway between two shortest candidates, where std takes the upper and zmij
//! the even one (the f64 with bits 0xc2a3905be4ee7ba0, −10755368974141.8125: std
//! `…141.813`, zmij `…141.812`). Such a value is an odd multiple of half the last digit's
//! unit, 10^k/2 = 5^k·2^(k−1), so its lowest set bit is 2^(k−1); wherever that bit is
//! elsewhere the nearest shortest candidate is unique and both give it. The unit tests
//! compare the text with std's for random bit patterns, short binary fractions (where
//! ties happen) and values of every scale.
//!
//! Measured (callgrind, `points.csv` of a one-plane sweep of the reference design, 6 768
//! lines): 219.2 M instructions with std's formatting, 96.1 M with this.

use std::fmt::Write as _;

use zmij::Buffer;

/// zmij's text of a finite, nonzero x, split at its point and exponent: `5.0`,
/// `0.001234` and `12.34` (fixed) or `1.5e-9`, `1.5e+20` (exponent). Both forms hold the
/// shortest round-trip digits; zmij uses the fixed one for decimal exponents −5..=15.
enum Text<'a> {
    /// Integer part, and the digits after the point (`"0"` for an integer).
    Fixed { int: &'a str, frac: &'a str },
    /// The first digit, the digits after the point (maybe none) and the exponent.
    Exp {
        lead: &'a str,
        rest: &'a str,
        exp: i32,
    },
}

/// A finite, nonzero x as zmij writes it: its sign and [`Text`].
struct Shortest<'a> {
    negative: bool,
    text: Text<'a>,
}

impl<'a> Shortest<'a> {
    /// x's text, or `None` where std is to print it: zero, a non-finite value and a
    /// possible tie (module doc).
    fn of(x: f64, buffer: &'a mut Buffer) -> Option<Self> {
        if x == 0.0 || !x.is_finite() {
            return None;
        }
        let all = buffer.format_finite(x);
        let negative = all.starts_with('-');
        let body = &all[usize::from(negative)..];
        // The exponent form ends in `e` and a signed exponent of one to three digits
        // (`e-6`, `e+20`, `e-310`); a fixed one's point is found from the front (within
        // three bytes for the sweep's numbers). `split_once` (memchr) cost more than the
        // formatting itself here.
        let bytes = body.as_bytes();
        let n = bytes.len();
        let e = [3, 4, 5]
            .into_iter()
            .find(|&k| n > k && bytes[n - k] == b'e');
        let text = match e {
            Some(k) => {
                let e = n - k;
                let sign = if bytes[e + 1] == b'-' { -1 } else { 1 };
                let exp = bytes[e + 2..]
                    .iter()
                    .fold(0i32, |acc, &c| acc * 10 + i32::from(c - b'0'));
                Text::Exp {
                    lead: &body[..1],
                    rest: if e > 1 { &body[2..e] } else { "" },
                    exp: sign * exp,
                }
            }
            None => match bytes.iter().position(|&c| c == b'.') {
                Some(p) => Text::Fixed {
                    int: &body[..p],
                    frac: &body[p + 1..],
                },
                None => Text::Fixed {
                    int: body,
                    frac: "0",
                },
            },
        };
        // The exponent of the last digit's unit, and that of x's lowest set bit.
        let last = match text {
            Text::Fixed { int, frac: "0" } => (int.len() - int.trim_end_matches('0').len()) as i32,
            Text::Fixed { frac, .. } => -(frac.len() as i32),
            Text::Exp { rest, exp, .. } => exp - rest.len() as i32,
        };
        let bits = x.to_bits();
        let (biased, fraction) = ((bits >> 52) & 0x7ff, bits & ((1 << 52) - 1));
        let (significand, binary) = if biased == 0 {
            (fraction, -1074)
        } else {
            (fraction | (1 << 52), biased as i32 - 1075)
        };
        let lowest_bit = binary + significand.trailing_zeros() as i32;
        (lowest_bit != last - 1).then_some(Self { negative, text })
    }

    /// The digits without leading or trailing zeros, and the decimal exponent of the
    /// first: |x| = d₁.d₂d₃… × 10^exponent.
    fn digits(&self) -> (String, i32) {
        match self.text {
            Text::Exp { lead, rest, exp } => (format!("{lead}{rest}"), exp),
            Text::Fixed { int: "0", frac } => {
                let significant = frac.trim_start_matches('0');
                let zeros = (frac.len() - significant.len()) as i32;
                (significant.to_string(), -zeros - 1)
            }
            Text::Fixed { int, frac } => {
                let all = format!("{int}{frac}");
                (all.trim_end_matches('0').to_string(), int.len() as i32 - 1)
            }
        }
    }
}

/// Appends `x` as `format!("{x}")` would.
pub fn push_display(out: &mut String, x: f64, buffer: &mut Buffer) {
    let Some(s) = Shortest::of(x, buffer) else {
        let _ = write!(out, "{x}");
        return;
    };
    if s.negative {
        out.push('-');
    }
    match s.text {
        // std's layout but for the integers' ".0".
        Text::Fixed { int, frac: "0" } => out.push_str(int),
        Text::Fixed { int, frac } => {
            out.push_str(int);
            out.push('.');
            out.push_str(frac);
        }
        Text::Exp { .. } => {
            let (digits, exponent) = s.digits();
            if exponent < 0 {
                out.push_str("0.");
                out.extend(std::iter::repeat_n('0', (-exponent - 1) as usize));
                out.push_str(&digits);
            } else {
                let whole = exponent as usize + 1;
                if digits.len() <= whole {
                    out.push_str(&digits);
                    out.extend(std::iter::repeat_n('0', whole - digits.len()));
                } else {
                    out.push_str(&digits[..whole]);
                    out.push('.');
                    out.push_str(&digits[whole..]);
                }
            }
        }
    }
}

/// Appends `x` as `format!("{x:e}")` would.
pub fn push_lower_exp(out: &mut String, x: f64, buffer: &mut Buffer) {
    let Some(s) = Shortest::of(x, buffer) else {
        let _ = write!(out, "{x:e}");
        return;
    };
    if s.negative {
        out.push('-');
    }
    let (lead, rest, exponent);
    let digits;
    match s.text {
        Text::Exp {
            lead: l,
            rest: r,
            exp,
        } => (lead, rest, exponent) = (l, r, exp),
        Text::Fixed { .. } => {
            let e;
            (digits, e) = s.digits();
            (lead, rest, exponent) = (&digits[..1], &digits[1..], e);
        }
    }
    out.push_str(lead);
    if !rest.is_empty() {
        out.push('.');
        out.push_str(rest);
    }
    out.push('e');
    if exponent < 0 {
        out.push('-');
    }
    let mut text = [0u8; 3];
    let mut n = exponent.unsigned_abs();
    let mut k = text.len();
    loop {
        k -= 1;
        text[k] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 {
            break;
        }
    }
    out.push_str(std::str::from_utf8(&text[k..]).expect("ASCII digits"));
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    fn check(x: f64, buffer: &mut Buffer) {
        let mut a = String::new();
        push_display(&mut a, x, buffer);
        assert_eq!(a, format!("{x}"), "{{}} of {x:e} (bits {:#x})", x.to_bits());
        let mut b = String::new();
        push_lower_exp(&mut b, x, buffer);
        assert_eq!(
            b,
            format!("{x:e}"),
            "{{:e}} of {x:e} (bits {:#x})",
            x.to_bits()
        );
    }

    #[test]
    fn the_text_is_std_s_for_special_and_edge_values() {
        let mut buffer = Buffer::new();
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            5.0,
            10.0,
            0.1,
            0.3,
            1e-4,
            9.999e-5,
            1e15,
            9.99e14,
            1e16,
            123456789012345680.0,
            1.5e-9,
            -3.25e-12,
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            f64::MIN,
            f64::EPSILON,
            std::f64::consts::PI,
            f64::from_bits(0xc2a3_905b_e4ee_7ba0),
            0.5,
            2.5,
            1e23,
            9007199254740993.0,
            2.0f64.powi(53),
            2.0f64.powi(53) + 2.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ] {
            check(x, &mut buffer);
        }
    }

    #[test]
    fn the_text_is_std_s_for_random_values_of_every_scale() {
        let mut buffer = Buffer::new();
        let mut rng = SplitMix64::new(20261127);
        for _ in 0..300_000 {
            // Any finite bit pattern.
            let x = f64::from_bits(rng.next_u64());
            if x.is_finite() {
                check(x, &mut buffer);
            }
            // The scales of the sweep's outputs (positions, q, tensions, rconds), short
            // and long digit strings alike.
            let scale = 10f64.powf(rng.uniform(-20.0, 20.0));
            let y = rng.uniform(-0.5, 0.5) * scale;
            check(y, &mut buffer);
            let short = (y * 1e3).round() / 1e3;
            check(short, &mut buffer);
            // Short binary fractions, where ties between two candidates happen.
            let bits = rng.next_u64();
            let dyadic = (bits >> (11 + bits % 40)) as f64 * 2f64.powi((bits % 121) as i32 - 60);
            check(dyadic, &mut buffer);
        }
    }
}
