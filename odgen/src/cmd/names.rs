//! `odgen names FILE`: the names the generated code gives a file's entries, with index, type,
//! access and unit, and the standard names (CiA 301, CiA 402) the client's profile traits offer.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use super::EXIT_TROUBLE;

/// `odgen names [--sidecar TOML] [--json] FILE`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The sidecar (units); default: `<stem>.toml` beside the file, if it exists; else the
    /// units the generator derives from the file's CiA 402 objects.
    #[arg(long, value_name = "TOML")]
    pub sidecar: Option<PathBuf>,
    /// One JSON object per line instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Only the names containing this text (case-insensitive).
    #[arg(long, value_name = "TEXT")]
    pub grep: Option<String>,
    /// The EDS or DCF file.
    pub file: PathBuf,
}

/// One generated name.
struct Row {
    index: u16,
    sub: u8,
    name: String,
    standard: Option<&'static str>,
    data_type: String,
    access: &'static str,
    unit: String,
}

/// Runs the subcommand.
pub fn run(args: Args) -> ExitCode {
    let Some(parsed) = super::read_or_report(&args.file, &eds::Options::lenient()) else {
        return ExitCode::from(EXIT_TROUBLE);
    };
    let shown = args.file.display().to_string();
    let sidecar_path = args.sidecar.clone().or_else(|| Some(args.file.with_extension("toml")).filter(|p| p.is_file()));
    let given = match sidecar_path {
        Some(p) => match od_codegen::sidecar::Sidecar::read(&p) {
            Ok(sc) => Some(sc),
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::from(EXIT_TROUBLE);
            }
        },
        None => None,
    };
    let sc = od_codegen::standard::effective_sidecar(&parsed.model, given.as_ref(), &shown);
    // The unit of each dimension in the first unit system (the default one comes last; the
    // first is the one a sidecar lists first).
    let unit_of = |d| -> String {
        let Some(sc) = &sc else { return String::new() };
        let systems: Vec<String> = sc
            .unit_systems
            .iter()
            .filter_map(|s| s.units.get(&d).map(|u| od_codegen::units::unit_symbol(u.unit).to_owned()))
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .collect();
        format!("{d:?} ({})", systems.join(" | "))
    };
    let mut rows = Vec::new();
    for (index, sub, name) in od_codegen::accessor_names(&parsed.model) {
        let Some(e) = parsed.model.entry(index, sub) else { continue };
        let standard = od_codegen::standard::object(index, sub).map(|o| o.name);
        let dim = sc
            .as_ref()
            .and_then(|s| s.dimension_of(index, sub))
            .or_else(|| od_codegen::standard::dimension(index, sub));
        rows.push(Row {
            index,
            sub,
            name,
            standard,
            data_type: e.data_type.name().to_owned(),
            access: e.access.as_str(),
            unit: dim.map(unit_of).unwrap_or_default(),
        });
    }
    if let Some(g) = &args.grep {
        let g = g.to_lowercase();
        rows.retain(|r| r.name.contains(&g) || r.standard.is_some_and(|s| s.contains(&g)));
    }
    let mut out = String::new();
    if args.json {
        for r in &rows {
            out.push_str("{\"index\":");
            let _ = write!(out, "{},\"sub\":{},\"name\":", r.index, r.sub);
            eds::diag::push_json_str(&mut out, &r.name);
            out.push_str(",\"standard\":");
            match r.standard {
                Some(s) => eds::diag::push_json_str(&mut out, s),
                None => out.push_str("null"),
            }
            out.push_str(",\"type\":");
            eds::diag::push_json_str(&mut out, &r.data_type);
            let _ = write!(out, ",\"access\":\"{}\",\"unit\":", r.access);
            eds::diag::push_json_str(&mut out, &r.unit);
            out.push_str("}\n");
        }
    } else {
        let w = rows.iter().map(|r| r.name.len()).max().unwrap_or(4).max(4);
        let sw = rows.iter().filter_map(|r| r.standard.map(str::len)).max().unwrap_or(8).max(8);
        let _ = writeln!(out, "{:<9} {:<w$} {:<sw$} {:<15} {:<6} unit", "index", "name", "standard", "type", "access");
        for r in &rows {
            let _ = writeln!(
                out,
                "{:<9} {:<w$} {:<sw$} {:<15} {:<6} {}",
                format!("{:04X}h:{}", r.index, r.sub),
                r.name,
                r.standard.unwrap_or("-"),
                r.data_type,
                r.access,
                r.unit
            );
        }
    }
    let mut stream = super::Stream::stdout();
    stream.push(&out);
    stream.finish();
    ExitCode::SUCCESS
}
