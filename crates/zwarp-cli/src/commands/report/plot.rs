//! Line charts of the report as SVG text (plotters' SVG backend), inlined into the page and
//! written next to it for the markdown summary.

use anyhow::{anyhow, Result};
use plotters::prelude::*;

/// One line of a chart.
pub struct Series {
    /// Legend entry.
    pub name: String,
    /// `(x, y)` points, in x order.
    pub points: Vec<(f64, f64)>,
    /// Dashed (the paper's numbers) or solid (ours).
    pub dashed: bool,
    /// Colour index into the palette (a paper line shares its colour with our matching line).
    pub color: usize,
}

/// A chart: axes, their labels and the lines.
pub struct Chart {
    /// Title above the plot area.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// Logarithmic x axis (base 2: N, S, speed factors).
    pub log_x: bool,
    /// The lines.
    pub series: Vec<Series>,
}

const WIDTH: u32 = 560;
const HEIGHT: u32 = 340;

fn color(i: usize) -> RGBColor {
    const C: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(23, 190, 207),
    ];
    C[i % C.len()]
}

/// The chart as an SVG document. Errors when no series has a finite point.
pub fn svg(chart: &Chart) -> Result<String> {
    let tx = |x: f64| if chart.log_x { x.log2() } else { x };
    let pts: Vec<(f64, f64)> = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|&(x, y)| (tx(x), y)))
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if pts.is_empty() {
        return Err(anyhow!("chart '{}': no finite point", chart.title));
    }
    let (mut x0, mut x1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (mut y0, mut y1) = pts.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    if x1 - x0 < 1e-9 {
        x0 -= 0.5;
        x1 += 0.5;
    }
    let pad = ((y1 - y0) * 0.08).max(1e-6 * y1.abs().max(1.0));
    y0 -= pad;
    y1 += pad;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, (WIDTH, HEIGHT)).into_drawing_area();
        let e = |e: &dyn std::fmt::Display| anyhow!("chart '{}': {e}", chart.title);
        root.fill(&WHITE).map_err(|x| e(&x))?;
        let mut c = ChartBuilder::on(&root)
            .caption(&chart.title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(52)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|x| e(&x))?;
        let log_x = chart.log_x;
        let fx = move |v: &f64| {
            let x = if log_x { 2f64.powf(*v) } else { *v };
            if (x - x.round()).abs() < 1e-6 {
                format!("{}", x.round())
            } else {
                format!("{x:.2}")
            }
        };
        c.configure_mesh()
            .x_desc(&chart.x_label)
            .y_desc(&chart.y_label)
            .x_label_formatter(&fx)
            .x_labels(if chart.log_x { ((x1 - x0).round() as usize + 1).clamp(2, 12) } else { 8 })
            .draw()
            .map_err(|x| e(&x))?;
        for s in &chart.series {
            let col = color(s.color);
            let line: Vec<(f64, f64)> =
                s.points.iter().map(|&(x, y)| (tx(x), y)).filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
            if line.is_empty() {
                continue;
            }
            let style = col.stroke_width(2);
            let anno = if s.dashed {
                c.draw_series(DashedLineSeries::new(line.clone(), 6, 4, style)).map_err(|x| e(&x))?
            } else {
                c.draw_series(LineSeries::new(line.clone(), style)).map_err(|x| e(&x))?
            };
            let dashed = s.dashed;
            anno.label(&s.name).legend(move |(x, y)| {
                let end = if dashed { x + 8 } else { x + 18 };
                PathElement::new(vec![(x, y), (end, y)], col.stroke_width(2))
            });
            c.draw_series(line.iter().map(|&p| Circle::new(p, 3, col.filled()))).map_err(|x| e(&x))?;
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|x| e(&x))?;
        root.present().map_err(|x| e(&x))?;
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn svg_has_every_series_and_label() {
        let chart = Chart {
            title: "speed-up".into(),
            x_label: "S".into(),
            y_label: "x".into(),
            log_x: true,
            series: vec![
                Series { name: "ours 512".into(), points: vec![(4.0, 2.0), (256.0, 40.0)], dashed: false, color: 0 },
                Series { name: "paper 512".into(), points: vec![(4.0, 1.4), (256.0, 3.4)], dashed: true, color: 0 },
            ],
        };
        let s = svg(&chart).unwrap();
        assert!(s.starts_with("<svg"));
        for t in ["speed-up", "ours 512", "paper 512", ">\n256\n<"] {
            assert!(s.contains(t), "missing {t:?}");
        }
        let empty = Chart { title: "e".into(), x_label: "".into(), y_label: "".into(), log_x: false, series: vec![] };
        assert!(svg(&empty).is_err());
    }
}
