//! The screen, drawn from the model alone: a title line, the nodes, the events, the frames and a
//! line of keys. Fits 80x24; larger terminals give the frames pane the room.

use std::time::Duration;

use ratatui::Frame;
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Color, Modifier, Style};
use ratatui::symbols;
use ratatui::text::{Line, Span};
use ratatui::widgets::{
    Axis, Block, Borders, Cell, Chart, Dataset, GraphType, List, ListItem, ListState, Paragraph, Row, Table, TableState,
};

use super::model::{Browser, Health, Model, Pane, Plot, PlotUnit, SeriesKey, mode_name, nmt_name, state_name};

/// Draws the whole screen at `now` (the time since the view started).
pub fn draw(f: &mut Frame, m: &Model, now: Duration) {
    // The plot takes room from the nodes pane (the selected node's row stays in view).
    let nodes_height = (m.nodes.len() as u16 + 4).clamp(5, if m.plot.is_some() { 7 } else { 12 });
    let [title, nodes, events, frames, keys] = Layout::vertical([
        Constraint::Length(1),
        Constraint::Length(nodes_height),
        Constraint::Percentage(35),
        Constraint::Min(4),
        Constraint::Length(1),
    ])
    .areas(f.area());
    draw_title(f, m, now, title);
    draw_nodes(f, m, now, nodes);
    if let Some(b) = &m.browser {
        draw_browser(f, b, events.union(frames));
    } else if let Some(plot) = &m.plot {
        draw_plot(f, m, plot, now, events.union(frames));
    } else {
        draw_events(f, m, events);
        draw_frames(f, m, frames);
    }
    draw_keys(f, m, keys);
}

/// The colours of a plot's series, in the order they were added.
const SERIES_COLOURS: [Color; 6] =
    [Color::Cyan, Color::Yellow, Color::LightMagenta, Color::LightGreen, Color::LightRed, Color::LightBlue];
/// The markers of the series within one panel, and the symbol the legend shows for each: a
/// series told apart without colour too.
const SERIES_MARKERS: [(symbols::Marker, &str); 3] = [
    (symbols::Marker::Braille, "\u{28ff}"),
    (symbols::Marker::Dot, "\u{2022}"),
    (symbols::Marker::HalfBlock, "\u{2584}"),
];

/// The plot in place of the events and frames: the last 30 s of the series shown, one panel a
/// unit (each with its own y-axis in that unit, all on one time axis; the series of a unit in one
/// panel, each its colour and marker, named in the panel's legend line with its latest value),
/// and the picker's line at the bottom.
fn draw_plot(f: &mut Frame, m: &Model, plot: &Plot, now: Duration, area: Rect) {
    // The last 30 s; until 30 s have passed, the time since the start, stretched.
    let t1 = now.as_secs_f64().max(1.0);
    let t0 = (t1 - 30.0).max(0.0);
    // The panels, in the order their first series was added.
    struct Shown<'a> {
        key: SeriesKey,
        label: &'a str,
        colour: Color,
        points: Vec<(f64, f64)>,
    }
    let mut panels: Vec<(PlotUnit, Vec<Shown>)> = Vec::new();
    for (i, &key) in plot.shown.iter().enumerate() {
        let Some((series, unit)) = m.series_info(key) else { continue };
        let points = held(&series.points, t0, t1, unit.per_raw);
        let shown = Shown { key, label: &series.label, colour: SERIES_COLOURS[i % SERIES_COLOURS.len()], points };
        match panels.iter_mut().find(|(u, _)| u.panel == unit.panel) {
            Some((_, list)) => list.push(shown),
            None => panels.push((unit, vec![shown])),
        }
    }
    let title = format!(" Plot: {} series, the last {:.0} s ", plot.shown.len(), t1 - t0);
    let outer = block(title, true);
    let inner = outer.inner(area);
    f.render_widget(outer, area);
    let [charts_area, pick_area] = Layout::vertical([Constraint::Fill(1), Constraint::Length(1)]).areas(inner);
    // The picked series, and whether it is shown.
    let pick = m.series_info(plot.pick).map_or(String::new(), |(s, u)| {
        let on = if plot.shown.contains(&plot.pick) { "shown, Space removes" } else { "Space adds" };
        format!("\u{25b8} node {} {} [{}]  ({on})", plot.pick.0, s.label, u.symbol)
    });
    f.render_widget(Paragraph::new(pick).style(Style::new().add_modifier(Modifier::BOLD)), pick_area);
    if panels.is_empty() {
        let hint = "no series shown: \u{2190}\u{2192} pick one, Space adds it";
        f.render_widget(Paragraph::new(hint).style(Style::new().fg(Color::DarkGray)), charts_area);
        return;
    }
    // As many panels as have room for a legend line and two rows of chart (eight dots of
    // Braille; the time axis takes two more rows under the last one).
    let fit = usize::from(charts_area.height.saturating_sub(2) / 3).max(1);
    if panels.len() > fit {
        let hidden: usize = panels[fit..].iter().map(|(_, list)| list.len()).sum();
        let note = format!(" {hidden} series in {} more units: a taller terminal shows them ", panels.len() - fit);
        f.render_widget(
            Paragraph::new(Line::from(Span::styled(note, Style::new().fg(Color::Yellow))).right_aligned()),
            Rect { height: 1, ..area },
        );
        panels.truncate(fit);
    }
    // Each panel's y range, and labels of one width, so that every panel's time axis starts in
    // the same column.
    let ranges: Vec<(f64, f64)> = panels
        .iter()
        .map(|(_, list)| {
            let (lo, hi) = list
                .iter()
                .flat_map(|s| s.points.iter())
                .fold((f64::MAX, f64::MIN), |(lo, hi), &(_, v)| (lo.min(v), hi.max(v)));
            if lo > hi {
                (0.0, 1.0)
            } else if (hi - lo).abs() < 1e-9 {
                (lo - 1.0, hi + 1.0)
            } else {
                (lo - (hi - lo) * 0.05, hi + (hi - lo) * 0.05)
            }
        })
        .collect();
    let label_width =
        ranges.iter().flat_map(|&(lo, hi)| [axis_number(lo).len(), axis_number(hi).len()]).max().unwrap_or(1);
    // Equal heights, the last panel two rows more for the time axis under it.
    let n = panels.len() as u16;
    let each = charts_area.height.saturating_sub(2) / n;
    let areas =
        Layout::vertical((0..n).map(|i| if i + 1 == n { Constraint::Fill(1) } else { Constraint::Length(each) }))
            .split(charts_area);
    for (i, ((unit, list), &(lo, hi))) in panels.iter().zip(&ranges).enumerate() {
        let last = i + 1 == panels.len();
        let [legend_area, chart_area] = Layout::vertical([Constraint::Length(1), Constraint::Fill(1)]).areas(areas[i]);
        let mut legend = vec![Span::styled(format!("[{}]", unit.symbol), Style::new().add_modifier(Modifier::BOLD))];
        for (j, s) in list.iter().enumerate() {
            let (_, symbol) = SERIES_MARKERS[j % SERIES_MARKERS.len()];
            let latest = s.points.last().map_or("-".to_owned(), |&(_, v)| axis_number(v));
            legend.push(Span::styled(format!(" {symbol} {} {} {latest}", s.key.0, s.label), Style::new().fg(s.colour)));
        }
        f.render_widget(Paragraph::new(Line::from(legend)), legend_area);
        let datasets: Vec<Dataset> = list
            .iter()
            .enumerate()
            .map(|(j, s)| {
                Dataset::default()
                    .marker(SERIES_MARKERS[j % SERIES_MARKERS.len()].0)
                    .graph_type(GraphType::Line)
                    .style(Style::new().fg(s.colour))
            })
            .collect();
        // At most four points a column of Braille dots (first, lowest, highest, last): what
        // the chart can show of thousands, at a fraction of the drawing.
        let columns = usize::from(chart_area.width.saturating_sub(label_width as u16 + 1)) * 2;
        let thinned: Vec<Vec<(f64, f64)>> = list.iter().map(|s| thin(&s.points, t0, t1, columns)).collect();
        let datasets: Vec<Dataset> = datasets.into_iter().zip(&thinned).map(|(d, p)| d.data(p)).collect();
        let y_labels = [format!("{:>label_width$}", axis_number(lo)), format!("{:>label_width$}", axis_number(hi))];
        let mut x_axis = Axis::default().bounds([t0, t1]);
        if last {
            x_axis = x_axis.labels([format!("{t0:.1}s"), format!("{t1:.1}s")]);
        }
        let chart = Chart::new(datasets)
            .legend_position(None)
            .x_axis(x_axis)
            .y_axis(Axis::default().bounds([lo, hi]).labels(y_labels));
        f.render_widget(chart, chart_area);
    }
}

/// The points of a series from `t0` to `t1`, in physical units, as steps: each value holds until
/// the next came (a TPDO sent on change says nothing between changes; a line drawn from one value
/// to the next would show values never sent), the last until `t1`, the one before `t0` from `t0`.
pub fn held(points: &std::collections::VecDeque<(f64, f64)>, t0: f64, t1: f64, per_raw: f64) -> Vec<(f64, f64)> {
    let first = points.partition_point(|&(t, _)| t < t0);
    let mut out = Vec::with_capacity(2 * (points.len() - first) + 2);
    if let Some(&(_, v)) = first.checked_sub(1).and_then(|i| points.get(i)) {
        out.push((t0, v * per_raw));
    }
    for &(t, v) in points.range(first..) {
        if let Some(&(_, before)) = out.last() {
            out.push((t, before));
        }
        out.push((t, v * per_raw));
    }
    if let Some(&(t, v)) = out.last()
        && t < t1
    {
        out.push((t1, v));
    }
    out
}

/// `points` (in time order) with at most four a column when `t0..t1` spans `columns` columns:
/// each column's first, lowest, highest and last, in time order.
pub fn thin(points: &[(f64, f64)], t0: f64, t1: f64, columns: usize) -> Vec<(f64, f64)> {
    if points.len() <= 4 * columns || columns == 0 || t1 <= t0 {
        return points.to_vec();
    }
    let column = |t: f64| (((t - t0) / (t1 - t0) * columns as f64) as usize).min(columns - 1);
    let mut out = Vec::with_capacity(4 * columns);
    let mut start = 0;
    while start < points.len() {
        let c = column(points[start].0);
        let end = start + points[start..].iter().take_while(|p| column(p.0) == c).count();
        let run = &points[start..end];
        let pick = |better: fn(f64, f64) -> bool| {
            (0..run.len()).fold(0, |best, i| if better(run[i].1, run[best].1) { i } else { best })
        };
        let mut picked = [0, pick(|a, b| a < b), pick(|a, b| a > b), run.len() - 1];
        picked.sort_unstable();
        let mut last = None;
        for i in picked {
            if last != Some(i) {
                out.push(run[i]);
                last = Some(i);
            }
        }
        start = end;
    }
    out
}

/// A number for an axis or a legend: fewer decimals as it grows.
fn axis_number(v: f64) -> String {
    match v.abs() {
        a if a >= 1000.0 => format!("{v:.0}"),
        a if a >= 10.0 => format!("{v:.1}"),
        _ => format!("{v:.2}"),
    }
}

/// The object browser in place of the events and frames: the entries the search passes around
/// the selected one, and the last answer (or the question before a write) at the bottom.
fn draw_browser(f: &mut Frame, b: &Browser, area: Rect) {
    let title = if b.searching || !b.query.is_empty() {
        format!(" Objects of node {} search: {}{} ", b.node, b.query, if b.searching { "_" } else { "" })
    } else {
        format!(" Objects of node {} ", b.node)
    };
    let outer = block(title, true);
    let inner = outer.inner(area);
    f.render_widget(outer, area);
    let [list_area, answer_area] = Layout::vertical([Constraint::Fill(1), Constraint::Length(1)]).areas(inner);
    let rows = usize::from(list_area.height).max(1);
    let first = b.selected.saturating_sub(rows - 1);
    let items: Vec<ListItem> = b
        .shown()
        .enumerate()
        .skip(first)
        .take(rows)
        .map(|(i, e)| {
            let line = format!(
                "{:04X}h:{:<3} {:<4} {:<12} {}",
                e.index,
                e.sub,
                e.access,
                format!("{:?}", e.data_type),
                e.name
            );
            let style = if i == b.selected { Style::new().add_modifier(Modifier::REVERSED) } else { Style::new() };
            ListItem::new(line).style(style)
        })
        .collect();
    f.render_widget(List::new(items), list_area);
    let answer = if let Some((_, _, _, q)) = &b.confirm {
        Span::styled(q.clone(), Style::new().fg(Color::Yellow).add_modifier(Modifier::BOLD))
    } else if let Some(edit) = &b.edit {
        Span::styled(format!("value: {edit}_"), Style::new().add_modifier(Modifier::BOLD))
    } else {
        Span::raw(b.result.clone().unwrap_or_default())
    };
    f.render_widget(Paragraph::new(Line::from(answer)), answer_area);
}

/// `12.345` seconds since the view started.
fn clock(at: Duration) -> String {
    format!("{:>7}.{:03}", at.as_secs(), at.subsec_millis())
}

/// An age in a few characters: `80ms`, `1.2s`, `5m03s`.
fn age(d: Duration) -> String {
    let ms = d.as_millis();
    if ms < 1000 {
        format!("{ms}ms")
    } else if ms < 60_000 {
        format!("{}.{}s", ms / 1000, ms % 1000 / 100)
    } else {
        format!("{}m{:02}s", ms / 60_000, ms % 60_000 / 1000)
    }
}

fn block(title: String, focused: bool) -> Block<'static> {
    let style = if focused { Style::new().fg(Color::Cyan).add_modifier(Modifier::BOLD) } else { Style::new() };
    Block::new().borders(Borders::ALL).title(Span::styled(title, style)).border_style(style)
}

fn draw_title(f: &mut Frame, m: &Model, now: Duration, area: Rect) {
    let mut spans = vec![
        Span::styled(" od-master top ", Style::new().add_modifier(Modifier::REVERSED)),
        Span::raw(format!(" {}  {} nodes  {} frames  t {}", m.bus, m.nodes.len(), m.frame_count, clock(now).trim())),
    ];
    if m.dropped > 0 {
        spans.push(Span::styled(format!("  {} dropped", m.dropped), Style::new().fg(Color::Red)));
    }
    f.render_widget(Paragraph::new(Line::from(spans)), area);
}

fn draw_nodes(f: &mut Frame, m: &Model, now: Duration, area: Rect) {
    let header = Row::new(["id", "name", "NMT", "heartbeat", "CiA 402", "mode", "position", "velocity", "EMCY"])
        .style(Style::new().add_modifier(Modifier::BOLD));
    let rows = m.nodes.values().map(|n| {
        let (health, hb_age) = n.health(now);
        let (hb, hb_style) = match health {
            Health::Unknown if !n.seen => ("not heard".to_owned(), Style::new().fg(Color::DarkGray)),
            Health::Unknown => ("-".to_owned(), Style::new()),
            Health::Alive => (format!("alive {}", hb_age.map(age).unwrap_or_default()), Style::new().fg(Color::Green)),
            Health::Late => (format!("late {}", hb_age.map(age).unwrap_or_default()), Style::new().fg(Color::Yellow)),
            Health::Lost => ("LOST".to_owned(), Style::new().fg(Color::Red).add_modifier(Modifier::BOLD)),
        };
        let d = n.drive.clone().unwrap_or_default();
        let state = d.status.map_or("-", short_state);
        let state_style = if state == "FAULT" { Style::new().fg(Color::Red) } else { Style::new() };
        let emcy = n.emcy.as_ref().map_or(String::new(), |e| format!("{:04X}h {}", e.code, e.text));
        // In the sidecar's units when it has them, else raw.
        let opt = |v: Option<i64>, unit: Option<(&str, f64)>| match (v, unit) {
            (None, _) => "-".to_owned(),
            (Some(v), None) => v.to_string(),
            (Some(v), Some((symbol, per_raw))) => physical(v as f64 * per_raw, symbol),
        };
        Row::new([
            Cell::new(format!("{:>3}", n.id)),
            Cell::new(n.name.clone().unwrap_or_else(|| "-".into())),
            Cell::new(nmt_name(n.nmt)),
            Cell::new(hb).style(hb_style),
            Cell::new(state).style(state_style),
            Cell::new(d.mode.map_or("-".into(), mode_name)),
            Cell::new(format!("{:>9}", opt(d.position, n.units[0]))),
            Cell::new(format!("{:>9}", opt(d.velocity, n.units[1]))),
            // Styled only when there is one: an empty red cell shows as a red block on the
            // selected (reversed) row.
            if emcy.is_empty() { Cell::new("") } else { Cell::new(emcy).style(Style::new().fg(Color::Red)) },
        ])
    });
    let widths = [
        Constraint::Length(3),
        Constraint::Length(9),
        Constraint::Length(7),
        Constraint::Length(10),
        Constraint::Length(14),
        Constraint::Length(4),
        Constraint::Length(9),
        Constraint::Length(9),
        Constraint::Fill(1),
    ];
    let [table_area, detail_area] =
        Layout::vertical([Constraint::Fill(1), Constraint::Length(1)]).areas(block(String::new(), false).inner(area));
    f.render_widget(block(" Nodes ".into(), m.focus == Pane::Nodes), area);
    let table = Table::new(rows, widths)
        .header(header)
        .column_spacing(1)
        .row_highlight_style(Style::new().add_modifier(Modifier::REVERSED));
    let mut state = TableState::new().with_selected((!m.nodes.is_empty()).then_some(m.selected));
    f.render_stateful_widget(table, table_area, &mut state);
    // The selected node in full: its CiA 402 state and its last EMCY with its age.
    let detail = m.selected_node().map_or(String::new(), |n| {
        let mut parts = vec![format!("node {}", n.id)];
        if let Some(s) = n.drive.as_ref().and_then(|d| d.status) {
            parts.push(format!("{} ({s:04X}h)", state_name(s)));
        }
        match &n.emcy {
            Some(e) => parts.push(format!("EMCY {:04X}h {} ({})", e.code, e.text, age(now.saturating_sub(e.at)))),
            None => parts.push("no EMCY".into()),
        }
        parts.join(", ")
    });
    f.render_widget(Paragraph::new(detail).style(Style::new().fg(Color::DarkGray)), detail_area);
}

/// A physical value in at most 9 characters where it can: fewer decimals as it grows.
fn physical(v: f64, symbol: &str) -> String {
    let room = 9usize.saturating_sub(symbol.len());
    for decimals in [2, 1, 0] {
        let s = format!("{v:.decimals$}");
        if s.len() <= room || decimals == 0 {
            return format!("{s}{symbol}");
        }
    }
    format!("{v:.0}{symbol}")
}

/// A CiA 402 state in at most 14 characters.
fn short_state(status: u16) -> &'static str {
    match state_name(status) {
        "Not ready to switch on" => "not ready",
        "Switch on disabled" => "sw-on disabled",
        "Ready to switch on" => "ready",
        "Switched on" => "switched on",
        "Operation enabled" => "op enabled",
        "Quick stop active" => "quick stop",
        "Fault reaction active" => "fault reaction",
        "Fault" => "FAULT",
        _ => "?",
    }
}

fn draw_events(f: &mut Frame, m: &Model, area: Rect) {
    let items: Vec<ListItem> = m
        .events
        .iter()
        .skip(m.scroll[0])
        .take(usize::from(area.height))
        .map(|(at, text)| ListItem::new(format!("{} {text}", clock(*at))))
        .collect();
    let title = format!(" Events ({}) ", m.events.len());
    f.render_widget(List::new(items).block(block(title, m.focus == Pane::Events)), area);
}

fn draw_frames(f: &mut Frame, m: &Model, area: Rect) {
    let items: Vec<ListItem> = m
        .shown_frames()
        .skip(m.scroll[1])
        .take(usize::from(area.height))
        .map(|l| ListItem::new(format!("{} {}", clock(l.at), l.text)))
        .collect();
    let mut title = " Frames".to_owned();
    if m.paused {
        title.push_str(" PAUSED");
    }
    let filter = m.filter.text();
    if !filter.is_empty() {
        title.push_str(&format!(" filter: {filter}"));
    }
    title.push(' ');
    let list = List::new(items).block(block(title, m.focus == Pane::Frames));
    f.render_stateful_widget(list, area, &mut ListState::default());
}

fn draw_keys(f: &mut Frame, m: &Model, area: Rect) {
    let line = if let Some(input) = &m.input {
        Line::from(vec![
            Span::styled("filter (node id, kind) Enter/Esc: ", Style::new().add_modifier(Modifier::BOLD)),
            Span::raw(format!("{input}_")),
        ])
    } else if let Some(status) = &m.status {
        Line::from(Span::styled(status.clone(), Style::new().fg(Color::Red)))
    } else if m.plot.is_some() {
        Line::from(" \u{2190}\u{2192} pick  Space add/remove  c clear  g/Esc back  q quit")
    } else if m.browser.is_some() {
        Line::from(" Enter read  w write  g plot  / search  \u{2191}\u{2193} select  Esc back  q quit")
    } else {
        Line::from(" q quit  Tab pane  \u{2191}\u{2193} select  o objects  g plot  p pause  / filter")
    };
    f.render_widget(Paragraph::new(line), area);
}
