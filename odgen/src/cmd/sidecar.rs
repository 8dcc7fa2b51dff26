//! `odgen sidecar FILE`: a starting sidecar for a description that has none, from its CiA 402
//! objects (what the generator uses when no sidecar is given: `od_codegen::standard`).

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use od_codegen::sidecar::{Sidecar, UnitSpec};
use od_codegen::units::unit_symbol;

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// `odgen sidecar FILE [-o OUT.toml]`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Write to this file instead of standard output (refused if it exists, unless `--force`).
    #[arg(short, long, value_name = "OUT.toml")]
    pub output: Option<PathBuf>,
    /// Overwrite the output file.
    #[arg(long)]
    pub force: bool,
    /// The EDS or DCF file.
    pub file: PathBuf,
}

/// Runs the subcommand: exit 0 with the sidecar written, 1 when the file has no CiA 402
/// object with a dimension (nothing to write), 2 when it cannot be read or written.
pub fn run(args: Args) -> ExitCode {
    let Some(parsed) = super::read_or_report(&args.file, &eds::Options::lenient()) else {
        return ExitCode::from(EXIT_TROUBLE);
    };
    let shown = args.file.display().to_string();
    let Some(sc) = od_codegen::standard::starting_sidecar(&parsed.model, &shown) else {
        eprintln!(
            "error: {shown} has no CiA 402 object with a dimension (positions, velocities, ...): there are no units \
             to describe"
        );
        return ExitCode::from(EXIT_FAILURE);
    };
    let text = render(&sc, &parsed.model);
    if let Err(e) = Sidecar::parse("odgen sidecar", &text) {
        eprintln!("error: the sidecar written does not read back (a bug in odgen, please report): {e}");
        return ExitCode::from(EXIT_TROUBLE);
    }
    match &args.output {
        None => {
            print!("{text}");
            ExitCode::SUCCESS
        }
        Some(p) if p.exists() && !args.force => {
            eprintln!("error: {} exists; `--force` overwrites it", p.display());
            ExitCode::from(EXIT_TROUBLE)
        }
        Some(p) => match odgen::safe_write::write(p, text.as_bytes()) {
            Ok(()) => {
                eprintln!("wrote {}: review it (units, scales) before use", p.display());
                ExitCode::SUCCESS
            }
            Err(e) => {
                eprintln!("error: cannot write {}: {e}", p.display());
                ExitCode::from(EXIT_TROUBLE)
            }
        },
    }
}

fn spec(s: &UnitSpec) -> String {
    let mut out = format!("{{ unit = \"{}\"", unit_symbol(s.unit));
    if s.scale != od_codegen::sidecar::Ratio::ONE {
        let _ = write!(out, ", scale = \"{}\"", s.scale);
    }
    if !s.scaled_by.is_empty() {
        let kinds: Vec<String> = s.scaled_by.iter().map(|k| format!("\"{}\"", kind(*k))).collect();
        let _ = write!(out, ", scaled_by = [{}]", kinds.join(", "));
    }
    out.push_str(" }");
    out
}

fn kind(k: od_codegen::sidecar::ScalingKind) -> &'static str {
    use od_codegen::sidecar::ScalingKind as K;
    match k {
        K::FeedConverter => "feed_converter",
        K::GearRatio => "gear_ratio",
        K::FeedConstant => "feed_constant",
        K::EncoderResolution => "encoder_resolution",
        K::VelocityFactor => "velocity_factor",
        K::ActuatorType => "actuator_type",
    }
}

fn dim(d: od_codegen::sidecar::Dimension) -> &'static str {
    use od_codegen::sidecar::Dimension as D;
    match d {
        D::Position => "position",
        D::Velocity => "velocity",
        D::Acceleration => "acceleration",
        D::Jerk => "jerk",
        D::Torque => "torque",
        D::Current => "current",
        D::TorqueSlope => "torque_slope",
        D::Time => "time",
    }
}

fn toml_str(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if c.is_control() => {
                let _ = write!(out, "\\u{:04X}", c as u32);
            }
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The sidecar as TOML, commented: each dimension with the vendor's name of its object.
pub fn render(sc: &Sidecar, model: &eds::Model) -> String {
    let mut t = String::new();
    t.push_str(
        "# A starting sidecar written by `odgen sidecar` from the description's CiA 402 objects.\n\
         # Check the units against the drive's manual and configuration, then keep it beside the\n\
         # description (same stem, .toml) or pass it to `Builder::sidecar` / `odgen gen --sidecar`.\n\n",
    );
    t.push_str("[device]\n");
    let _ = writeln!(t, "name = {}", toml_str(&sc.device.name));
    let _ = writeln!(t, "eds = {}", toml_str(&sc.device.eds));
    if let Some(v) = sc.device.vendor.as_deref().filter(|v| !v.trim().is_empty()) {
        let _ = writeln!(t, "vendor = {}", toml_str(v));
    }
    t.push_str("\n# The dimension of each motion object (CiA 402).\n[dimensions]\n");
    for (r, d) in &sc.dimensions {
        let name = model.entry(r.index, r.sub_or_zero()).map(|e| e.name.to_string()).unwrap_or_default();
        let key = if r.sub_or_zero() == 0 { format!("\"0x{:04X}\"", r.index) } else { format!("\"{r}\"") };
        let _ = writeln!(t, "{key:<14} = {:<16} # {}", format!("\"{}\"", dim(*d)), name.replace('\n', " "));
    }
    for s in &sc.unit_systems {
        t.push_str("\n[[unit_system]]\n");
        let _ = writeln!(t, "name = {}", toml_str(&s.name));
        if let Some(d) = &s.description {
            let _ = writeln!(t, "description = {}", toml_str(d));
        }
        if !s.when.is_empty() {
            let conds: Vec<String> = s
                .when
                .iter()
                .map(|c| format!("{{ object = \"{}\", equals = \"0x{:X}\" }}", c.object, c.equals.0))
                .collect();
            let _ = writeln!(t, "when = [{}]", conds.join(", "));
        }
        t.push_str("[unit_system.units]\n");
        for (d, u) in &s.units {
            let _ = writeln!(t, "{} = {}", dim(*d), spec(u));
        }
    }
    for so in &sc.scaling {
        t.push_str("\n[[scaling]]\n");
        let _ = writeln!(t, "object = \"{}\"", so.object);
        let _ = writeln!(t, "kind = \"{}\"", kind(so.kind));
        let subs: Vec<String> = so.subs.iter().map(|(k, v)| format!("{k} = {v}")).collect();
        let _ = writeln!(t, "subs = {{ {} }}", subs.join(", "));
        let _ = writeln!(t, "formula = {}", toml_str(&so.formula));
        let dims: Vec<String> = so.applies_to.iter().map(|d| format!("\"{}\"", dim(*d))).collect();
        let _ = writeln!(t, "applies_to = [{}]", dims.join(", "));
        if let Some(n) = &so.note {
            let _ = writeln!(t, "note = {}", toml_str(n));
        }
    }
    t
}
