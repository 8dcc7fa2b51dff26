//! Traces: CSV and SVG plots of known moves (the DRVI's Figures 4.1, 4.2 and 4.4).

use crate::motion_common;

use std::collections::BTreeMap;

use drive::motion::{Axis, AxisConfig, Mode, PlantConfig};
use drive::trace::{PlotOptions, Quantity, Sample, Trace};
use motion_common::*;

// ------------------------------------------------------------------------------------------
// A minimal XML reader: enough to prove the SVG is well-formed and to query it.

#[derive(Debug)]
struct Element {
    name: String,
    attrs: BTreeMap<String, String>,
    children: Vec<Element>,
    text: String,
}

impl Element {
    fn all<'a>(&'a self, name: &str, out: &mut Vec<&'a Element>) {
        if self.name == name {
            out.push(self);
        }
        for c in &self.children {
            c.all(name, out);
        }
    }

    fn find(&self, name: &str) -> Vec<&Element> {
        let mut out = Vec::new();
        self.all(name, &mut out);
        out
    }

    fn attr(&self, key: &str) -> &str {
        self.attrs.get(key).map(String::as_str).unwrap_or_else(|| panic!("<{}> has no {key}", self.name))
    }

    fn num(&self, key: &str) -> f64 {
        self.attr(key).parse().unwrap_or_else(|e| panic!("{key}={:?}: {e}", self.attr(key)))
    }
}

fn check_entities(s: &str) -> Result<(), String> {
    let mut rest = s;
    while let Some(i) = rest.find('&') {
        let tail = &rest[i..];
        let end = tail.find(';').ok_or_else(|| format!("unterminated entity in {s:?}"))?;
        let name = &tail[1..end];
        let ok = matches!(name, "amp" | "lt" | "gt" | "quot" | "apos")
            || (name.starts_with('#') && name[1..].chars().all(|c| c.is_ascii_digit()) && name.len() > 1);
        if !ok {
            return Err(format!("bad entity &{name};"));
        }
        rest = &tail[end + 1..];
    }
    if s.contains('<') {
        return Err(format!("raw < in {s:?}"));
    }
    Ok(())
}

fn parse_xml(doc: &str) -> Result<Element, String> {
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    let mut i = 0;
    let b = doc.as_bytes();
    while i < b.len() {
        if b[i] != b'<' {
            let end = doc[i..].find('<').map_or(doc.len(), |k| i + k);
            let text = &doc[i..end];
            check_entities(text)?;
            match stack.last_mut() {
                Some(e) => e.text.push_str(text),
                None if text.trim().is_empty() => {}
                None => return Err(format!("text outside the root: {text:?}")),
            }
            i = end;
            continue;
        }
        let end = doc[i..].find('>').ok_or("unterminated tag")? + i;
        let tag = &doc[i + 1..end];
        i = end + 1;
        if let Some(name) = tag.strip_prefix('/') {
            let e = stack.pop().ok_or_else(|| format!("</{name}> without an open element"))?;
            if e.name != name {
                return Err(format!("</{name}> closes <{}>", e.name));
            }
            match stack.last_mut() {
                Some(parent) => parent.children.push(e),
                None if root.is_none() => root = Some(e),
                None => return Err("two roots".into()),
            }
            continue;
        }
        let (tag, empty) = match tag.strip_suffix('/') {
            Some(t) => (t, true),
            None => (tag, false),
        };
        let name_end = tag.find(char::is_whitespace).unwrap_or(tag.len());
        let name = &tag[..name_end];
        if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == ':') {
            return Err(format!("bad element name {name:?}"));
        }
        let mut attrs = BTreeMap::new();
        let mut rest = tag[name_end..].trim_start();
        while !rest.is_empty() {
            let eq = rest.find('=').ok_or_else(|| format!("attribute without value in <{name}>: {rest:?}"))?;
            let key = rest[..eq].trim();
            if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '-' || c == ':') {
                return Err(format!("bad attribute name {key:?}"));
            }
            let after = &rest[eq + 1..];
            let value_body = after.strip_prefix('"').ok_or_else(|| format!("unquoted attribute {key} in <{name}>"))?;
            let close = value_body.find('"').ok_or("unterminated attribute")?;
            let value = &value_body[..close];
            check_entities(value)?;
            if attrs.insert(key.to_owned(), value.to_owned()).is_some() {
                return Err(format!("duplicate attribute {key} in <{name}>"));
            }
            rest = value_body[close + 1..].trim_start();
        }
        let e = Element { name: name.to_owned(), attrs, children: Vec::new(), text: String::new() };
        if empty {
            match stack.last_mut() {
                Some(parent) => parent.children.push(e),
                None => return Err("empty root".into()),
            }
        } else {
            stack.push(e);
        }
    }
    if let Some(open) = stack.last() {
        return Err(format!("<{}> not closed", open.name));
    }
    root.ok_or_else(|| "no root element".into())
}

#[test]
fn xml_checker_rejects_broken_documents() {
    assert!(parse_xml("<svg><g></svg>").is_err());
    assert!(parse_xml("<svg a=1></svg>").is_err());
    assert!(parse_xml("<svg a=\"1\" a=\"2\"></svg>").is_err());
    assert!(parse_xml("<svg>a & b</svg>").is_err());
    assert!(parse_xml("<svg></svg><svg></svg>").is_err());
    assert!(parse_xml("<svg><g/></svg>").is_ok());
}

// ------------------------------------------------------------------------------------------

/// A panel's series: (data-min, data-max) and the pixel rows its polyline spans.
struct Plotted {
    min: f64,
    max: f64,
    top_px: f64,
    bottom_px: f64,
}

fn panel<'a>(svg: &'a Element, quantity: &str) -> &'a Element {
    svg.find("g").into_iter().find(|g| g.attrs.get("data-quantity").map(String::as_str) == Some(quantity)).unwrap()
}

fn series(panel: &Element, name: &str) -> Plotted {
    let line = panel.find("polyline").into_iter().find(|p| p.attr("data-series") == name).unwrap();
    let ys: Vec<f64> = line
        .attr("points")
        .split_whitespace()
        .map(|pt| pt.split_once(',').unwrap().1.parse::<f64>().unwrap())
        .collect();
    Plotted {
        min: line.num("data-min"),
        max: line.num("data-max"),
        top_px: ys.iter().copied().fold(f64::INFINITY, f64::min),
        bottom_px: ys.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    }
}

/// The pixel row of `value` in `panel` (from its data attributes).
fn y_px(panel: &Element, value: f64) -> f64 {
    let (lo, hi) = (panel.num("data-y-min"), panel.num("data-y-max"));
    let (top, bottom) = (panel.num("data-top"), panel.num("data-bottom"));
    bottom - (value - lo) / (hi - lo) * (bottom - top)
}

fn tick_labels(panel: &Element) -> Vec<String> {
    let g = panel.find("g").into_iter().find(|g| g.attrs.get("class").map(String::as_str) == Some("y-ticks")).unwrap();
    g.find("text").iter().map(|t| t.text.clone()).collect()
}

fn out_file(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name)
}

/// The DRVI's Figure 4.2: 720° at 60 rpm, 60 rpm/s, recorded with a plausible statusword.
fn figure_4_2() -> Trace {
    let cfg = AxisConfig {
        units: drvi_motor_units(),
        profile_velocity: 6000,
        profile_acceleration: 60,
        profile_deceleration: 60,
        plant: PlantConfig { inertia: 0.001, ..PlantConfig::default() },
        ..AxisConfig::default()
    };
    let mut axis = enabled(cfg, Mode::ProfilePosition);
    let mut trace = Trace::new();
    let record = |axis: &Axis, trace: &mut Trace| {
        let s = axis.status();
        let sw =
            0x0237 | if s.target_reached { 1 << 10 } else { 0 } | if s.set_point_acknowledge { 1 << 12 } else { 0 };
        trace.record(&s, sw);
    };
    record(&axis, &mut trace);
    go_to(&mut axis, 72_000);
    for _ in 0..3500 {
        axis.step(1000);
        record(&axis, &mut trace);
    }
    trace
}

#[test]
fn svg_of_a_known_move_is_well_formed_and_shows_its_extremes() {
    let trace = figure_4_2();
    let text =
        trace.to_svg(&PlotOptions { title: "DRVI Figure 4.2 <positioning> & speed".into(), ..PlotOptions::default() });
    std::fs::write(out_file("drvi-figure-4-2.svg"), &text).unwrap();
    let svg = parse_xml(&text).unwrap();
    assert_eq!(svg.name, "svg");
    assert_eq!(svg.attr("xmlns"), "http://www.w3.org/2000/svg");
    assert_eq!(svg.find("title")[0].text, "DRVI Figure 4.2 &lt;positioning&gt; &amp; speed");
    // One panel per quantity, each with a legend.
    let panels: Vec<&str> =
        svg.find("g").iter().filter_map(|g| g.attrs.get("data-quantity")).map(String::as_str).collect();
    assert_eq!(panels, ["position", "velocity", "torque", "mode", "statusword"]);
    for q in &panels {
        let legend =
            panel(&svg, q).find("g").into_iter().find(|g| g.attrs.get("class").map(String::as_str) == Some("legend"));
        assert!(!legend.unwrap().find("text").is_empty(), "{q} has a legend");
    }
    // Position: 0 to 72 000, drawn from the bottom of the axis range to its 72 000 row.
    let position = panel(&svg, "position");
    let actual = series(position, "actual");
    assert_eq!((actual.min, actual.max), (0.0, 72_000.0));
    assert!((actual.top_px - y_px(position, 72_000.0)).abs() < 0.01);
    assert!((actual.bottom_px - y_px(position, 0.0)).abs() < 0.01);
    assert_eq!(tick_labels(position), ["0", "20000", "40000", "60000", "80000"]);
    // Velocity: peak 6000 (60 rpm), demand and actual alike.
    let velocity = panel(&svg, "velocity");
    for name in ["demand", "actual"] {
        let v = series(velocity, name);
        assert_eq!((v.min, v.max), (0.0, 6000.0), "{name}");
        assert!((v.top_px - y_px(velocity, 6000.0)).abs() < 0.01);
    }
    // Torque: ±J·a = ±0.001 · 36 000 = ±36 while accelerating and braking.
    let torque = series(panel(&svg, "torque"), "actual");
    assert_eq!((torque.min, torque.max), (-36.0, 36.0));
    // Mode 1 throughout; the target-reached lane goes low during the move and high at the end.
    assert_eq!(series(panel(&svg, "mode"), "mode").max, 1.0);
    let lane = series(panel(&svg, "statusword"), "bit 10: target reached");
    assert_eq!((lane.min, lane.max), (1.2, 1.8));
}

#[test]
fn csv_of_a_known_move() {
    let trace = figure_4_2();
    let csv = trace.to_csv();
    std::fs::write(out_file("drvi-figure-4-2.csv"), &csv).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 3502);
    assert_eq!(lines[0], drive::trace::CSV_HEADER);
    assert_eq!(lines[1000], "999000,1,567,17964,17964,5994,5994,36,36");
    // The torque of a sample is that of the step ending there: the last braking millisecond.
    assert_eq!(lines[3001], "3000000,1,1591,72000,72000,0,0,-36,-36");
    assert_eq!(lines[3002], "3001000,1,1591,72000,72000,0,0,0,0");
    assert_eq!(Trace::from_csv(&csv).unwrap(), trace);
    let mut written = Vec::new();
    trace.write_csv(&mut written).unwrap();
    assert_eq!(written, csv.as_bytes());
}

#[test]
fn scaled_quantities_and_other_figures() {
    // Figure 4.1: speed profile in rpm, positions in degrees.
    let cfg = AxisConfig {
        units: drvi_motor_units(),
        profile_acceleration: 60,
        profile_deceleration: 60,
        ..AxisConfig::default()
    };
    let mut axis = enabled(cfg, Mode::ProfileVelocity);
    let mut trace = Trace::with_interval(10_000);
    axis.set_target_velocity(6000).unwrap();
    for ms in 0..4000 {
        if ms == 2000 {
            axis.set_target_velocity(0).unwrap();
        }
        axis.step(1000);
        trace.record(&axis.status(), 0x0237);
    }
    let options = PlotOptions {
        title: "DRVI Figure 4.1: speed profile".into(),
        position: Quantity { label: "Position".into(), unit: "°".into(), scale: 0.01 },
        velocity: Quantity { label: "Speed".into(), unit: "rpm".into(), scale: 0.01 },
        torque: Quantity { label: "Current".into(), unit: "mA".into(), scale: 1.0 },
        ..PlotOptions::default()
    };
    let text = trace.to_svg(&options);
    std::fs::write(out_file("drvi-figure-4-1.svg"), &text).unwrap();
    let svg = parse_xml(&text).unwrap();
    assert_eq!(series(panel(&svg, "velocity"), "actual").max, 60.0);
    assert_eq!(series(panel(&svg, "position"), "actual").max, 720.0);
    assert_eq!(tick_labels(panel(&svg, "velocity")), ["0", "20", "40", "60"]);
    assert_eq!(trace.samples().len(), 400);

    // Figure 4.4: torque (current) profile, 1000 mA/s to 1000 mA and back at 2 s.
    let cfg = AxisConfig {
        torque_slope: 1000,
        plant: PlantConfig { inertia: 0.1, viscous: 0.05, ..PlantConfig::default() },
        ..AxisConfig::default()
    };
    let mut axis = enabled(cfg, Mode::ProfileTorque);
    let mut trace = Trace::new();
    axis.set_target_torque(1000);
    for ms in 0..4000 {
        if ms == 2000 {
            axis.set_target_torque(0);
        }
        axis.step(1000);
        trace.record(&axis.status(), 0x0237);
    }
    let text = trace.to_svg(&PlotOptions { title: "DRVI Figure 4.4: torque profile".into(), ..PlotOptions::default() });
    std::fs::write(out_file("drvi-figure-4-4.svg"), &text).unwrap();
    let svg = parse_xml(&text).unwrap();
    let torque = series(panel(&svg, "torque"), "demand");
    assert_eq!((torque.min, torque.max), (0.0, 1000.0));
    assert!((torque.top_px - y_px(panel(&svg, "torque"), 1000.0)).abs() < 0.01);
}

#[test]
fn long_traces_are_decimated_without_losing_extremes() {
    let mut trace = Trace::new();
    for i in 0..200_000u64 {
        // A sawtooth with one spike in the middle.
        let v = if i == 123_457 { 1_000_000 } else { (i % 1000) as i32 };
        trace.push(Sample { time_us: i * 100, position_actual: v, position_demand: -v, ..Sample::default() });
    }
    let text = trace.to_svg(&PlotOptions::default());
    assert!(text.len() < 400_000, "{} bytes", text.len());
    let svg = parse_xml(&text).unwrap();
    let position = panel(&svg, "position");
    let actual = series(position, "actual");
    assert_eq!(actual.max, 1_000_000.0);
    assert!((actual.top_px - y_px(position, 1_000_000.0)).abs() < 0.01);
    let demand = series(position, "demand");
    assert!((demand.bottom_px - y_px(position, -1_000_000.0)).abs() < 0.01);
}

#[test]
fn empty_and_flat_traces_still_make_valid_documents() {
    let svg = parse_xml(&Trace::new().to_svg(&PlotOptions::default())).unwrap();
    assert_eq!(svg.name, "svg");
    let mut trace = Trace::new();
    trace.push(Sample { time_us: 5, position_actual: 42, ..Sample::default() });
    let text =
        trace.to_svg(&PlotOptions { width: 1, panel_height: 1, statusword_bits: vec![], ..PlotOptions::default() });
    let svg = parse_xml(&text).unwrap();
    let position = panel(&svg, "position");
    assert!(position.num("data-y-min") < 42.0 && position.num("data-y-max") > 42.0);
}
