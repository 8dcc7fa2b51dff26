//! Hand-written SVG plots of a trace.
//!
//! The document is a stack of panels sharing the time axis. Each panel carries its data range
//! and pixel mapping as `data-` attributes (`data-y-min`, `data-y-max`: the axis range;
//! `data-top`, `data-bottom`: its pixel rows), and each series its extremes (`data-min`,
//! `data-max`), so a test or a script can check a plot without rendering it.

use std::fmt::Write as _;

use super::Sample;

/// How one physical quantity is labelled and scaled on its panel.
#[derive(Debug, Clone, PartialEq)]
pub struct Quantity {
    /// Panel title, e.g. "Position".
    pub label: String,
    /// Unit shown on the axis, e.g. "°".
    pub unit: String,
    /// Displayed value = raw value × scale (e.g. 0.01 for positions in 0.01°).
    pub scale: f64,
}

impl Quantity {
    /// A quantity shown in raw units.
    pub fn raw(label: &str) -> Quantity {
        Quantity { label: label.to_owned(), unit: "raw".to_owned(), scale: 1.0 }
    }

    fn scale(&self) -> f64 {
        if self.scale.is_finite() && self.scale != 0.0 { self.scale } else { 1.0 }
    }
}

/// Layout and labels of a plot.
#[derive(Debug, Clone, PartialEq)]
pub struct PlotOptions {
    /// Title above the panels.
    pub title: String,
    /// Width of the document in pixels.
    pub width: u32,
    /// Height of each panel's plot area in pixels.
    pub panel_height: u32,
    /// The position panel.
    pub position: Quantity,
    /// The velocity panel.
    pub velocity: Quantity,
    /// The torque panel.
    pub torque: Quantity,
    /// Statusword bits drawn as lanes, with their names.
    pub statusword_bits: Vec<(u8, String)>,
}

impl Default for PlotOptions {
    fn default() -> Self {
        PlotOptions {
            title: "Motion trace".to_owned(),
            width: 900,
            panel_height: 150,
            position: Quantity::raw("Position"),
            velocity: Quantity::raw("Velocity"),
            torque: Quantity::raw("Torque"),
            statusword_bits: vec![
                (2, "operation enabled".to_owned()),
                (10, "target reached".to_owned()),
                (11, "internal limit".to_owned()),
                (12, "bit 12 (mode)".to_owned()),
                (13, "bit 13 (mode)".to_owned()),
                (14, "bit 14".to_owned()),
            ],
        }
    }
}

const LEFT: f64 = 90.0;
const RIGHT: f64 = 200.0;
const TOP: f64 = 50.0;
const GAP: f64 = 60.0;
const BOTTOM: f64 = 50.0;
const DEMAND: &str = "#1f77b4";
const ACTUAL: &str = "#d62728";
const LANE_COLOURS: [&str; 8] =
    ["#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf", "#ff7f0e"];

/// Escapes text for element content and attribute values.
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            c if (c as u32) < 0x20 && c != '\n' && c != '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// "Nice" axis ticks covering `lo..=hi`: a step of 1, 2 or 5 × 10^k and the tick values.
pub(crate) fn ticks(lo: f64, hi: f64, target: usize) -> (f64, f64, f64, Vec<f64>) {
    let (mut lo, mut hi) = if lo.is_finite() && hi.is_finite() { (lo.min(hi), lo.max(hi)) } else { (0.0, 1.0) };
    if hi - lo < 1e-12 * lo.abs().max(hi.abs()).max(1e-300) || hi == lo {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        lo -= pad;
        hi += pad;
    }
    let raw = (hi - lo) / target.max(2) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let norm = raw / mag;
    let step = mag
        * if norm <= 1.0 {
            1.0
        } else if norm <= 2.0 {
            2.0
        } else if norm <= 5.0 {
            5.0
        } else {
            10.0
        };
    let first = (lo / step).floor() * step;
    let last = (hi / step).ceil() * step;
    let n = ((last - first) / step).round().clamp(1.0, 1000.0) as usize;
    let values = (0..=n).map(|i| first + i as f64 * step).collect();
    (first, last, step, values)
}

/// A tick label with as many decimals as the step needs.
fn label(value: f64, step: f64) -> String {
    let decimals = if step >= 1.0 { 0 } else { (-step.log10().floor()).clamp(0.0, 9.0) as usize };
    let s = format!("{value:.decimals$}");
    if s.trim_start_matches('-').chars().all(|c| c == '0' || c == '.') {
        s.trim_start_matches('-').to_owned()
    } else {
        s
    }
}

/// Maps data to pixels for one panel.
struct Frame {
    x0: f64,
    x1: f64,
    t0: f64,
    t1: f64,
    top: f64,
    bottom: f64,
    y_min: f64,
    y_max: f64,
}

impl Frame {
    fn x(&self, t: f64) -> f64 {
        self.x0 + (t - self.t0) / (self.t1 - self.t0) * (self.x1 - self.x0)
    }

    fn y(&self, v: f64) -> f64 {
        self.bottom - (v - self.y_min) / (self.y_max - self.y_min) * (self.bottom - self.top)
    }
}

/// Points of a line through `(t, v)`, keeping per pixel column the first, lowest, highest and
/// last point so the extremes survive any number of samples.
fn decimated(frame: &Frame, points: &[(f64, f64)]) -> String {
    let mut out = String::new();
    let mut i = 0;
    while i < points.len() {
        let col = frame.x(points[i].0).floor();
        let mut j = i;
        let (mut lo, mut hi) = (i, i);
        while j < points.len() && frame.x(points[j].0).floor() == col {
            if points[j].1 < points[lo].1 {
                lo = j;
            }
            if points[j].1 > points[hi].1 {
                hi = j;
            }
            j += 1;
        }
        let mut keep = [i, lo, hi, j - 1];
        keep.sort_unstable();
        let mut prev = usize::MAX;
        for k in keep {
            if k != prev {
                let (t, v) = points[k];
                let _ = write!(out, "{:.2},{:.2} ", frame.x(t), frame.y(v));
                prev = k;
            }
        }
        i = j;
    }
    out.trim_end().to_owned()
}

/// Points of a step line (the value holds until the next sample).
fn stepped(frame: &Frame, points: &[(f64, f64)]) -> String {
    let mut out = String::new();
    let mut last: Option<f64> = None;
    for &(t, v) in points {
        match last {
            Some(prev) if prev == v => continue,
            Some(prev) => {
                let _ = write!(out, "{:.2},{:.2} ", frame.x(t), frame.y(prev));
            }
            None => {}
        }
        let _ = write!(out, "{:.2},{:.2} ", frame.x(t), frame.y(v));
        last = Some(v);
    }
    if let (Some(v), Some(&(t, _))) = (last, points.last()) {
        let _ = write!(out, "{:.2},{:.2}", frame.x(t), frame.y(v));
    }
    out.trim_end().to_owned()
}

/// Time/value points of a line.
type Points = Vec<(f64, f64)>;
/// Picks the (demand, actual) pair of a quantity from a sample.
type Pick = fn(&Sample) -> (i32, i32);

struct Series<'a> {
    name: &'a str,
    colour: &'a str,
    dashed: bool,
    points: Points,
}

#[allow(clippy::too_many_arguments)]
fn panel(
    out: &mut String,
    quantity: &str,
    title: &str,
    unit: &str,
    top: f64,
    options: &PlotOptions,
    t_range: (f64, f64),
    series: &[Series],
    step_lines: bool,
    lanes: Option<&[(u8, String)]>,
) {
    let width = f64::from(options.width.max(300));
    let height = f64::from(options.panel_height.max(60));
    let (x0, x1) = (LEFT, width - RIGHT);
    let bottom = top + height;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for &(_, v) in &s.points {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    let (y_min, y_max, y_step, y_ticks) = match lanes {
        // Lanes: a grid line between each, labels at their centres (drawn below).
        Some(l) => {
            let n = l.len().max(1);
            (0.0, n as f64, 1.0, (0..=n).map(|k| k as f64).collect())
        }
        // Integer-valued step lines (the mode): integer ticks with a margin of one.
        None if step_lines => {
            let (lo, hi, step, _) = ticks(lo - 1.0, hi + 1.0, 5);
            let step = step.max(1.0).round();
            let (lo, hi) = ((lo / step).floor() * step, (hi / step).ceil() * step);
            let n = ((hi - lo) / step).round().clamp(1.0, 1000.0) as usize;
            (lo, hi, step, (0..=n).map(|k| lo + k as f64 * step).collect())
        }
        None => ticks(lo, hi, 5),
    };
    let (t_min, t_max, t_step, t_ticks) = ticks(t_range.0, t_range.1, 10);
    let frame = Frame { x0, x1, t0: t_min, t1: t_max, top, bottom, y_min, y_max };
    let _ = writeln!(
        out,
        r#"<g class="panel" data-quantity="{}" data-y-min="{}" data-y-max="{}" data-top="{:.2}" data-bottom="{:.2}">"#,
        esc(quantity),
        y_min,
        y_max,
        top,
        bottom
    );
    let _ = writeln!(
        out,
        r#"<text x="{:.2}" y="{:.2}" font-size="13" font-weight="bold">{}</text>"#,
        x0,
        top - 8.0,
        esc(title)
    );
    let _ = writeln!(
        out,
        r##"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" fill="#fbfbfb" stroke="#333"/>"##,
        x0,
        top,
        x1 - x0,
        height
    );
    // Grid and tick labels.
    let _ = writeln!(out, r##"<g class="grid" stroke="#ddd" stroke-width="1">"##);
    for &t in &t_ticks {
        let x = frame.x(t);
        let _ = writeln!(out, r#"<line x1="{x:.2}" y1="{top:.2}" x2="{x:.2}" y2="{bottom:.2}"/>"#);
    }
    for &v in &y_ticks {
        let y = frame.y(v);
        let _ = writeln!(out, r#"<line x1="{x0:.2}" y1="{y:.2}" x2="{x1:.2}" y2="{y:.2}"/>"#);
    }
    let _ = writeln!(out, "</g>");
    let _ = writeln!(out, r#"<g class="x-ticks" text-anchor="middle">"#);
    for &t in &t_ticks {
        let _ = writeln!(out, r#"<text x="{:.2}" y="{:.2}">{}</text>"#, frame.x(t), bottom + 14.0, label(t, t_step));
    }
    let _ = writeln!(out, "</g>");
    let _ = writeln!(out, r#"<text x="{:.2}" y="{:.2}" text-anchor="end">t [s]</text>"#, x1, bottom + 28.0);
    let _ = writeln!(out, r#"<g class="y-ticks" text-anchor="end">"#);
    match lanes {
        Some(lanes) => {
            for (k, (bit, _)) in lanes.iter().enumerate() {
                let y = frame.y(k as f64 + 0.5);
                let _ = writeln!(out, r#"<text x="{:.2}" y="{:.2}">bit {}</text>"#, x0 - 6.0, y + 4.0, bit);
            }
        }
        None => {
            for &v in &y_ticks {
                let _ = writeln!(
                    out,
                    r#"<text x="{:.2}" y="{:.2}">{}</text>"#,
                    x0 - 6.0,
                    frame.y(v) + 4.0,
                    label(v, y_step)
                );
            }
        }
    }
    let _ = writeln!(out, "</g>");
    if !unit.is_empty() {
        let (ux, uy) = (18.0, (top + bottom) / 2.0);
        let _ = writeln!(
            out,
            r#"<text x="{ux:.2}" y="{uy:.2}" text-anchor="middle" transform="rotate(-90 {ux:.2} {uy:.2})">{}</text>"#,
            esc(unit)
        );
    }
    // Series.
    for s in series {
        if s.points.is_empty() {
            continue;
        }
        let (min, max) = s.points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.1), b.max(p.1)));
        let points = if step_lines { stepped(&frame, &s.points) } else { decimated(&frame, &s.points) };
        let dash = if s.dashed { r#" stroke-dasharray="6 3""# } else { "" };
        let _ = writeln!(
            out,
            r#"<polyline class="series" data-series="{}" data-min="{}" data-max="{}" fill="none" stroke="{}" stroke-width="1.5"{} points="{}"/>"#,
            esc(s.name),
            min,
            max,
            s.colour,
            dash,
            points
        );
    }
    // Legend.
    let lx = x1 + 12.0;
    let _ = writeln!(out, r#"<g class="legend">"#);
    for (k, s) in series.iter().enumerate() {
        let y = top + 12.0 + 16.0 * k as f64;
        let dash = if s.dashed { r#" stroke-dasharray="6 3""# } else { "" };
        let _ = writeln!(
            out,
            r#"<line x1="{lx:.2}" y1="{y:.2}" x2="{:.2}" y2="{y:.2}" stroke="{}" stroke-width="2"{dash}/>"#,
            lx + 24.0,
            s.colour
        );
        let _ = writeln!(out, r#"<text x="{:.2}" y="{:.2}">{}</text>"#, lx + 30.0, y + 4.0, esc(s.name));
    }
    let _ = writeln!(out, "</g>");
    let _ = writeln!(out, "</g>");
}

/// Renders `samples` as an SVG document.
pub(crate) fn render(samples: &[Sample], options: &PlotOptions) -> String {
    let width = f64::from(options.width.max(300));
    let height = f64::from(options.panel_height.max(60));
    let panels = 5.0;
    let total_height = TOP + panels * height + (panels - 1.0) * GAP + BOTTOM;
    let t: Vec<f64> = samples.iter().map(|s| s.time_us as f64 * 1e-6).collect();
    let t_range = match (t.first(), t.last()) {
        (Some(&a), Some(&b)) => (a, b),
        _ => (0.0, 1.0),
    };
    let pair = |q: &Quantity, f: Pick| -> (Points, Points) {
        let k = q.scale();
        samples
            .iter()
            .zip(&t)
            .map(|(s, &t)| {
                let (d, a) = f(s);
                ((t, f64::from(d) * k), (t, f64::from(a) * k))
            })
            .unzip()
    };
    let mut out = String::with_capacity(4096 + samples.len() * 64);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="11">"#,
        w = width,
        h = total_height
    );
    let _ = writeln!(out, "<title>{}</title>", esc(&options.title));
    let _ = writeln!(out, r#"<rect x="0" y="0" width="{width}" height="{total_height}" fill="white"/>"#);
    let _ = writeln!(
        out,
        r#"<text x="{:.2}" y="24" text-anchor="middle" font-size="15" font-weight="bold">{}</text>"#,
        width / 2.0,
        esc(&options.title)
    );
    let mut top = TOP;
    let quantities: [(&str, &Quantity, Pick); 3] = [
        ("position", &options.position, |s| (s.position_demand, s.position_actual)),
        ("velocity", &options.velocity, |s| (s.velocity_demand, s.velocity_actual)),
        ("torque", &options.torque, |s| (s.torque_demand, s.torque_actual)),
    ];
    for (name, q, f) in quantities {
        let (demand, actual) = pair(q, f);
        let series = [
            Series { name: "demand", colour: DEMAND, dashed: true, points: demand },
            Series { name: "actual", colour: ACTUAL, dashed: false, points: actual },
        ];
        panel(&mut out, name, &q.label, &q.unit, top, options, t_range, &series, false, None);
        top += height + GAP;
    }
    let mode: Vec<(f64, f64)> = samples.iter().zip(&t).map(|(s, &t)| (t, f64::from(s.mode))).collect();
    let series = [Series { name: "mode", colour: "#333", dashed: false, points: mode }];
    panel(&mut out, "mode", "Mode of operation", "6061h", top, options, t_range, &series, true, None);
    top += height + GAP;
    let lanes = &options.statusword_bits;
    let names: Vec<String> = lanes.iter().map(|(bit, name)| format!("bit {bit}: {name}")).collect();
    let series: Vec<Series> = lanes
        .iter()
        .enumerate()
        .map(|(k, (bit, _))| Series {
            name: &names[k],
            colour: LANE_COLOURS[k % LANE_COLOURS.len()],
            dashed: false,
            points: samples
                .iter()
                .zip(&t)
                .map(|(s, &t)| {
                    let on = *bit < 16 && s.statusword & (1u16 << *bit) != 0;
                    (t, k as f64 + if on { 0.8 } else { 0.2 })
                })
                .collect(),
        })
        .collect();
    panel(&mut out, "statusword", "Statusword", "6041h", top, options, t_range, &series, true, Some(lanes));
    out.push_str("</svg>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_ticks() {
        let (lo, hi, step, v) = ticks(0.0, 7200.0, 5);
        assert_eq!((lo, hi, step), (0.0, 8000.0, 2000.0));
        assert_eq!(v, vec![0.0, 2000.0, 4000.0, 6000.0, 8000.0]);
        let (lo, hi, step, _) = ticks(-0.3, 0.7, 5);
        assert_eq!(step, 0.2);
        assert!(lo <= -0.3 && hi >= 0.7);
        let (lo, hi, _, _) = ticks(5.0, 5.0, 5);
        assert!(lo < 5.0 && hi > 5.0);
        let (lo, hi, _, _) = ticks(f64::NAN, 1.0, 5);
        assert_eq!((lo, hi), (0.0, 1.0));
    }

    #[test]
    fn labels() {
        assert_eq!(label(0.30000000000000004, 0.1), "0.3");
        assert_eq!(label(-0.0, 0.5), "0.0");
        assert_eq!(label(2000.0, 1000.0), "2000");
        assert_eq!(esc("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
    }
}
