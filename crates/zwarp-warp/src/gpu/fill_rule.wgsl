// The FillRule::Background decision (zwarp_warp::holes::hole_fill), shared by warp.wgsl's dilate
// pass and holes.wgsl's fills: both shaders are compiled with this file in front of them.

// A converged pixel in the warp's state buffers: PixelState::Converged (0), or 3, converged on a
// layer after the first (WarpOutput::revealed).
fn is_converged(s: u32) -> bool {
    return s == 0u || s == 3u;
}

// zwarp_warp::holes::BRACKET_SPAN_RATIO.
const BRACKET_SPAN_RATIO: f32 = 4.0;
// zwarp_warp::holes::FAR_SIDE_SPREAD.
const FAR_SIDE_SPREAD: f32 = 0.25;

// From the four directions' bracket span (-1: not bracketed), far side's depth and its distance,
// and the narrowest span: the far sides of the directions bracketed within BRACKET_SPAN_RATIO
// times the narrowest, averaged over those within FAR_SIDE_SPREAD of the farthest with
// inverse-distance weights (as offsets from the farthest): (depth, 1), or (0, 0) if none crosses.
fn far_sides(span: array<f32, 4>, far: array<f32, 4>, far_d: array<f32, 4>, narrowest: f32) -> vec2<f32> {
    var found = false;
    var z = 0.0;
    for (var j = 0; j < 4; j++) {
        if (span[j] >= 0.0 && span[j] <= BRACKET_SPAN_RATIO * narrowest) {
            z = select(far[j], max(z, far[j]), found);
            found = true;
        }
    }
    if (!found) {
        return vec2<f32>(0.0, 0.0);
    }
    var num = 0.0;
    var den = 0.0;
    for (var j = 0; j < 4; j++) {
        if (span[j] >= 0.0 && span[j] <= BRACKET_SPAN_RATIO * narrowest && z - far[j] <= FAR_SIDE_SPREAD * (1.0 - z)) {
            num += (z - far[j]) / far_d[j];
            den += 1.0 / far_d[j];
        }
    }
    return vec2<f32>(z - num / den, 1.0);
}
