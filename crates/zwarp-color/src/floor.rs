//! The streaming floor of a colour warp (ARCHITECTURE.md "The floor is the yardstick"): the
//! least memory traffic any colour warp of this field needs — read every term's motion planes,
//! the source depth and the colour once, write one colour per target pixel — timed as a parallel
//! pass that does exactly that. A warp's `floor_ratio` is its time over this pass's time in the
//! same run.

use rayon::prelude::*;
use zwarp_core::{Image, Result};

use crate::field::Field;
use crate::heuristic::check_color;

/// Rows per parallel chunk of the floor pass.
const ROWS: usize = 8;

/// One floor pass: `out[i] = color[i] + 0 * (sum of the field's planes and the depth at i)`, so
/// that no load can be dropped; the loop vectorises (planes are structure-of-arrays).
pub fn floor_pass(field: &Field<'_>, color: &Image<[f32; 3]>, out: &mut Image<[f32; 3]>) -> Result<()> {
    check_color(field, color)?;
    let (w, h) = field.size();
    if out.size() != (w, h) {
        *out = Image::new(w, h, [0.0; 3]);
    }
    let wu = w as usize;
    let terms = field.terms();
    let depth = field.depth();
    let src = color.data();
    out.data_mut().par_chunks_mut(wu * ROWS).enumerate().for_each(|(c, rows)| {
        let i0 = c * wu * ROWS;
        // Blocks of 256 texels: the partial sums stay in registers / L1.
        for (b, rows) in rows.chunks_mut(256).enumerate() {
            let (s0, n) = (i0 + b * 256, rows.len());
            let mut acc = [0.0f32; 256];
            let acc = &mut acc[..n];
            acc.copy_from_slice(&depth[s0..s0 + n]);
            for t in terms {
                for ((a, x), y) in acc.iter_mut().zip(&t.x[s0..s0 + n]).zip(&t.y[s0..s0 + n]) {
                    *a += x + y;
                }
            }
            for ((o, s), a) in rows.iter_mut().zip(&src[s0..s0 + n]).zip(acc.iter()) {
                let z = 0.0 * a;
                *o = [s[0] + z, s[1] + z, s[2] + z];
            }
        }
    });
    Ok(())
}

/// Median, min and max (ms) of `reps` (at least `zwarp_warp::floor::FLOOR_MIN_REPS`, for the
/// reason given there) timed [`floor_pass`]es after one warm-up, into a buffer allocated once:
/// the `floor_ms` of the colour-warp commands.
pub fn floor_ms(field: &Field<'_>, color: &Image<[f32; 3]>, reps: usize) -> Result<(f64, f64, f64)> {
    let mut out = Image::new(0, 0, [0.0f32; 3]);
    floor_pass(field, color, &mut out)?;
    let reps = reps.max(zwarp_warp::floor::FLOOR_MIN_REPS);
    let mut t = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t0 = std::time::Instant::now();
        floor_pass(field, color, &mut out)?;
        t.push(t0.elapsed().as_secs_f64() * 1e3);
    }
    t.sort_by(f64::total_cmp);
    Ok((t[t.len() / 2], t[0], t[t.len() - 1]))
}
