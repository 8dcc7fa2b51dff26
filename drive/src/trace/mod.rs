//! Motion traces: a recorder of demand and actual values over time, written as CSV and drawn as
//! an SVG plot like the figures of the drive manuals (DRVI Figures 4.1 to 4.4).
//!
//! ```
//! use drive::motion::{Axis, AxisConfig, Mode};
//! use drive::trace::{PlotOptions, Trace};
//!
//! let mut axis = Axis::new(AxisConfig { profile_acceleration: 100, profile_deceleration: 100, ..AxisConfig::default() });
//! axis.set_power(true);
//! axis.set_mode(Mode::ProfileVelocity);
//! axis.set_target_velocity(100).unwrap();
//! let mut trace = Trace::new();
//! for _ in 0..2000 {
//!     axis.step(1000);
//!     trace.record(&axis.status(), 0x0237);
//! }
//! let csv = trace.to_csv();
//! assert!(csv.starts_with("time_us,mode,statusword,"));
//! let svg = trace.to_svg(&PlotOptions::default());
//! assert!(svg.starts_with("<svg"));
//! ```

mod svg;

use std::fmt::Write as _;
use std::io;

use crate::motion::Status;

pub use svg::{PlotOptions, Quantity};

/// One row of a trace: the values a drive exposes, at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Sample {
    /// Simulated time, µs.
    pub time_us: u64,
    /// Mode of operation display (6061h).
    pub mode: i8,
    /// Statusword (6041h).
    pub statusword: u16,
    /// Position demand (6062h).
    pub position_demand: i32,
    /// Position actual (6064h).
    pub position_actual: i32,
    /// Velocity demand (606Bh).
    pub velocity_demand: i32,
    /// Velocity actual (606Ch).
    pub velocity_actual: i32,
    /// Torque demand (6074h).
    pub torque_demand: i32,
    /// Torque actual (6077h).
    pub torque_actual: i32,
}

impl Sample {
    /// The sample for an axis status and the statusword the drive built from it.
    pub fn from_status(status: &Status, statusword: u16) -> Sample {
        Sample {
            time_us: status.time_us,
            mode: status.mode.code(),
            statusword,
            position_demand: status.position_demand,
            position_actual: status.position_actual,
            velocity_demand: status.velocity_demand,
            velocity_actual: status.velocity_actual,
            torque_demand: status.torque_demand,
            torque_actual: status.torque_actual,
        }
    }
}

/// The CSV header, in column order.
pub const CSV_HEADER: &str = "time_us,mode,statusword,position_demand,position_actual,velocity_demand,velocity_actual,torque_demand,torque_actual";

/// A CSV line that [`Trace::from_csv`] could not read.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("line {line}: {message}")]
pub struct CsvError {
    /// 1-based line number.
    pub line: usize,
    /// What is wrong.
    pub message: String,
}

/// A recorder of [`Sample`]s in time order.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Trace {
    samples: Vec<Sample>,
    interval_us: u64,
}

impl Trace {
    /// An empty trace that keeps every sample.
    pub fn new() -> Trace {
        Trace::default()
    }

    /// An empty trace that keeps at most one sample per `interval_us` (a 1 ms simulation
    /// recorded every 10 ms keeps a long run small).
    pub fn with_interval(interval_us: u64) -> Trace {
        Trace { samples: Vec::new(), interval_us }
    }

    /// Records the axis status with the statusword the drive built from it.
    pub fn record(&mut self, status: &Status, statusword: u16) {
        self.push(Sample::from_status(status, statusword));
    }

    /// Appends a sample. Samples older than the last one, or closer to it than the interval,
    /// are dropped.
    pub fn push(&mut self, sample: Sample) {
        if let Some(last) = self.samples.last()
            && (sample.time_us < last.time_us
                || (self.interval_us > 0 && sample.time_us - last.time_us < self.interval_us))
        {
            return;
        }
        self.samples.push(sample);
    }

    /// The samples, oldest first.
    pub fn samples(&self) -> &[Sample] {
        &self.samples
    }

    /// Writes the trace as CSV: [`CSV_HEADER`], then one line per sample (integers, the
    /// statusword in decimal).
    pub fn write_csv<W: io::Write>(&self, mut w: W) -> io::Result<()> {
        w.write_all(self.to_csv().as_bytes())
    }

    /// The trace as CSV text.
    pub fn to_csv(&self) -> String {
        let mut out = String::with_capacity(64 * (self.samples.len() + 1));
        out.push_str(CSV_HEADER);
        out.push('\n');
        for s in &self.samples {
            // Writing to a String cannot fail.
            let _ = writeln!(
                out,
                "{},{},{},{},{},{},{},{},{}",
                s.time_us,
                s.mode,
                s.statusword,
                s.position_demand,
                s.position_actual,
                s.velocity_demand,
                s.velocity_actual,
                s.torque_demand,
                s.torque_actual
            );
        }
        out
    }

    /// Reads CSV written by [`Trace::to_csv`].
    pub fn from_csv(text: &str) -> Result<Trace, CsvError> {
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, header)) if header.trim_end() == CSV_HEADER => {}
            _ => return Err(CsvError { line: 1, message: format!("expected the header `{CSV_HEADER}`") }),
        }
        let mut trace = Trace::new();
        for (i, line) in lines {
            let line_no = i + 1;
            let line = line.trim_end();
            if line.is_empty() {
                continue;
            }
            let fields: Vec<&str> = line.split(',').collect();
            if fields.len() != 9 {
                return Err(CsvError { line: line_no, message: format!("expected 9 fields, found {}", fields.len()) });
            }
            let err = |col: usize, e: &dyn std::fmt::Display| CsvError {
                line: line_no,
                message: format!("column {} `{}`: {e}", col + 1, fields[col]),
            };
            let int = |col: usize| fields[col].parse::<i32>().map_err(|e| err(col, &e));
            let sample = Sample {
                time_us: fields[0].parse().map_err(|e| err(0, &e))?,
                mode: fields[1].parse().map_err(|e| err(1, &e))?,
                statusword: fields[2].parse().map_err(|e| err(2, &e))?,
                position_demand: int(3)?,
                position_actual: int(4)?,
                velocity_demand: int(5)?,
                velocity_actual: int(6)?,
                torque_demand: int(7)?,
                torque_actual: int(8)?,
            };
            if let Some(last) = trace.samples.last()
                && sample.time_us < last.time_us
            {
                return Err(CsvError { line: line_no, message: "time goes backwards".into() });
            }
            trace.samples.push(sample);
        }
        Ok(trace)
    }

    /// Draws the trace as a standalone SVG document: one panel per quantity (position,
    /// velocity, torque with demand and actual; mode; statusword bits), each with axes, tick
    /// labels and a legend.
    pub fn to_svg(&self, options: &PlotOptions) -> String {
        svg::render(&self.samples, options)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_round_trip_and_errors() {
        let mut t = Trace::new();
        t.push(Sample { time_us: 0, mode: 1, statusword: 0x1237, position_demand: -5, ..Sample::default() });
        t.push(Sample { time_us: 1000, mode: 1, torque_actual: i32::MIN, ..Sample::default() });
        let csv = t.to_csv();
        assert_eq!(Trace::from_csv(&csv).unwrap(), t);
        assert_eq!(Trace::from_csv("nope").unwrap_err().line, 1);
        let bad = format!("{CSV_HEADER}\n0,1,2,3\n");
        assert_eq!(
            Trace::from_csv(&bad).unwrap_err(),
            CsvError { line: 2, message: "expected 9 fields, found 4".into() }
        );
        let bad = format!("{CSV_HEADER}\n0,1,2,3,x,5,6,7,8\n");
        assert!(Trace::from_csv(&bad).unwrap_err().message.starts_with("column 5 `x`"));
        let back = format!("{CSV_HEADER}\n5,0,0,0,0,0,0,0,0\n4,0,0,0,0,0,0,0,0\n");
        assert_eq!(Trace::from_csv(&back).unwrap_err().line, 3);
    }

    #[test]
    fn interval_thins_samples() {
        let mut t = Trace::with_interval(10_000);
        for i in 0..100u64 {
            t.push(Sample { time_us: i * 1000, ..Sample::default() });
        }
        assert_eq!(t.samples().len(), 10);
        t.push(Sample { time_us: 5, ..Sample::default() });
        assert_eq!(t.samples().len(), 10);
    }
}
