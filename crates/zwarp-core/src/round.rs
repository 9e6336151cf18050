//! `floor` and `ceil` of `f32` without a function call. The default x86-64 target has no
//! SSE4.1 `roundss`, so `f32::floor` / `f32::ceil` are calls into a software routine, made per
//! pixel in loops whose own arithmetic is a handful of instructions (the triplanar pattern of
//! every colour render, the VR grid's colour fetch, the culling rectangles; `floorf` was 2.7 %
//! of a `zwarp vr` run). These give exactly `f32::floor` / `f32::ceil` for every input (signed
//! zeros, NaN, infinities and values beyond `i32` included), so replacing one with the other
//! changes no result.

/// `v.floor()`, bit for bit, inlined.
#[inline(always)]
pub fn floor(v: f32) -> f32 {
    // From 2^23 on every f32 is an integer (the infinities too); NaN stays NaN.
    if v.is_nan() || v.abs() >= 8_388_608.0 {
        return v;
    }
    let t = v as i32 as f32;
    if t > v {
        t - 1.0
    } else if t == v {
        // An integer, or -0.0: keep its own sign of zero.
        v
    } else {
        t
    }
}

/// `v.ceil()`, bit for bit, inlined.
#[inline(always)]
pub fn ceil(v: f32) -> f32 {
    if v.is_nan() || v.abs() >= 8_388_608.0 {
        return v;
    }
    let t = v as i32 as f32;
    if t < v {
        t + 1.0
    } else if t == v {
        v
    } else if t == 0.0 {
        // -1 < v < 0 truncates to +0.0; ceil keeps the sign: -0.0.
        -0.0
    } else {
        t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_and_ceil_equal_the_std_ones_bit_for_bit() {
        let mut values = vec![
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            1.5,
            -1.5,
            0.999_999_94,
            -0.999_999_94,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-40,
            -1e-40,
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            -8_388_609.0,
            2_147_483_648.0,
            -2_147_483_904.0,
            3e9,
            -3e9,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        // A sweep across magnitudes, both signs, with fractions.
        let mut x = 1e-6f32;
        while x < 1e10 {
            values.extend([x, -x, x + 0.25, -x - 0.25, x.next_up(), -x.next_up()]);
            x *= 1.37;
        }
        for v in values {
            assert_eq!(floor(v).to_bits(), v.floor().to_bits(), "floor({v:e})");
            assert_eq!(ceil(v).to_bits(), v.ceil().to_bits(), "ceil({v:e})");
        }
        assert!(floor(f32::NAN).is_nan() && ceil(f32::NAN).is_nan());
    }
}
