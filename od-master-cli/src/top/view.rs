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

use super::model::{Browser, Health, Model, Pane, mode_name, nmt_name, state_name};

/// Draws the whole screen at `now` (the time since the view started).
pub fn draw(f: &mut Frame, m: &Model, now: Duration) {
    let nodes_height = (m.nodes.len() as u16 + 4).clamp(5, 12);
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
    } else if let Some((node, at)) = m.plot {
        draw_plot(f, m, node, at, now, events.union(frames));
    } else {
        draw_events(f, m, events);
        draw_frames(f, m, frames);
    }
    draw_keys(f, m, keys);
}

/// The last 30 s of one series of a node, in physical units where its sidecar gives them.
fn draw_plot(f: &mut Frame, m: &Model, node: u8, at: usize, now: Duration, area: Rect) {
    let Some(row) = m.nodes.get(&node) else { return };
    let Some((&(index, sub), series)) = row.series.iter().nth(at) else { return };
    let (unit, per_raw) = row.unit_of(index, sub).map_or(("raw", 1.0), |(u, k)| (u, k));
    let t1 = now.as_secs_f64().max(30.0);
    let t0 = t1 - 30.0;
    let points: Vec<(f64, f64)> =
        series.points.iter().filter(|(t, _)| *t >= t0).map(|&(t, v)| (t, v * per_raw)).collect();
    let (lo, hi) = points.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &(_, v)| (lo.min(v), hi.max(v)));
    let (lo, hi) = if points.is_empty() {
        (0.0, 1.0)
    } else if (hi - lo).abs() < 1e-9 {
        (lo - 1.0, hi + 1.0)
    } else {
        (lo - (hi - lo) * 0.05, hi + (hi - lo) * 0.05)
    };
    let title =
        format!(" node {node} {} [{unit}] ({} of {}, \u{2191}\u{2193}) ", series.label, at + 1, row.series.len());
    let dataset = Dataset::default()
        .marker(symbols::Marker::Braille)
        .graph_type(GraphType::Line)
        .style(Style::new().fg(Color::Cyan))
        .data(&points);
    let chart = Chart::new(vec![dataset])
        .block(block(title, true))
        .x_axis(Axis::default().bounds([t0, t1]).labels([format!("{t0:.0}s"), format!("{t1:.0}s")]))
        .y_axis(Axis::default().bounds([lo, hi]).labels([format!("{lo:.1}"), format!("{hi:.1}")]));
    f.render_widget(chart, area);
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
            Cell::new(emcy).style(Style::new().fg(Color::Red)),
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
        Line::from(" \u{2191}\u{2193} series  g/Esc back  q quit")
    } else if m.browser.is_some() {
        Line::from(" Enter read  w write  / search  \u{2191}\u{2193} select  Esc back  q quit")
    } else {
        Line::from(" q quit  Tab pane  \u{2191}\u{2193} select  o objects  g plot  p pause  / filter")
    };
    f.render_widget(Paragraph::new(line), area);
}
