//! Naming an object on the command line: `6041h`, `0x6041`, `1018h:1`, `0x1018:1`, or (with an
//! EDS) the accessor name the generated code gives the entry (`statusword`,
//! `identity_object.vendor_id`).

use eds::{DataType, Model};

/// An entry of a device's dictionary as the command line named it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Target {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The entry's accessor name, when an EDS named it.
    pub name: Option<String>,
    /// The entry's data type, when an EDS gives it.
    pub data_type: Option<DataType>,
    /// The entry's access, when an EDS gives it.
    pub access: Option<eds::model::Access>,
}

impl Target {
    /// Why the EDS says this entry cannot be written (read-only or constant), if it does.
    pub fn not_writable(&self) -> Option<String> {
        use eds::model::Access;
        let access = self.access.filter(|a| matches!(a, Access::Ro | Access::Const))?;
        Some(format!(
            "{} is {} in the EDS given (AccessType {}): not written",
            self.describe(),
            if access == Access::Const { "constant" } else { "read-only" },
            access.as_str()
        ))
    }

    /// Why the EDS says this entry cannot be read (write-only), if it does.
    pub fn not_readable(&self) -> Option<String> {
        let access = self.access.filter(|a| *a == eds::model::Access::Wo)?;
        Some(format!("{} is write-only in the EDS given (AccessType {}): not read", self.describe(), access.as_str()))
    }

    /// `6041h sub 0 (statusword)`.
    fn describe(&self) -> String {
        let name = self.name.as_deref().map(|n| format!(" ({n})")).unwrap_or_default();
        format!("{:04X}h sub {}{name}", self.index, self.sub)
    }
}

/// Parses `6041h`, `0x6041`, `6041` (hex) with an optional `:sub` (decimal, or hex with `h`/`0x`).
pub fn parse_numeric(text: &str) -> Option<(u16, u8)> {
    let (index, sub) = match text.split_once(':') {
        Some((i, s)) => (i, Some(s)),
        None => (text, None),
    };
    let index = parse_hex_index(index.trim())?;
    let sub = match sub {
        None => 0,
        Some(s) => parse_sub(s.trim())?,
    };
    Some((index, sub))
}

fn parse_hex_index(s: &str) -> Option<u16> {
    let digits = if let Some(d) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        d
    } else if let Some(d) = s.strip_suffix('h').or_else(|| s.strip_suffix('H')) {
        d
    } else {
        // A bare four-digit number is an index in hex, as every CANopen document writes it.
        if s.len() != 4 {
            return None;
        }
        s
    };
    if digits.is_empty() || digits.len() > 4 || !digits.chars().all(|c| c.is_ascii_hexdigit()) {
        return None;
    }
    u16::from_str_radix(digits, 16).ok()
}

fn parse_sub(s: &str) -> Option<u8> {
    if let Some(d) = s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        return u8::from_str_radix(d, 16).ok();
    }
    if let Some(d) = s.strip_suffix('h').or_else(|| s.strip_suffix('H')) {
        return u8::from_str_radix(d, 16).ok();
    }
    s.parse().ok()
}

/// Why an object could not be named.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ObjectError {
    /// Neither an index nor (without an EDS) a name.
    #[error("`{0}` is not an object: write an index such as 6041h, 0x6041, 1018h:1, or give --eds to use names")]
    Syntax(String),
    /// A name the EDS does not have.
    #[error("no entry of {file} is named `{name}`{}", suggest(.suggestions))]
    UnknownName {
        /// The name given.
        name: String,
        /// The EDS.
        file: String,
        /// The closest names.
        suggestions: Vec<String>,
    },
}

fn suggest(names: &[String]) -> String {
    if names.is_empty() { String::new() } else { format!("; closest: {}", names.join(", ")) }
}

/// The names of a model's entries: the generated accessor names, and `object.rest` where the
/// accessor starts with its object's name.
pub struct Names {
    file: String,
    /// `(name, index, sub)`, the accessor names first.
    names: Vec<(String, u16, u8)>,
}

impl Names {
    /// The names od-codegen gives `model`'s entries.
    pub fn new(file: &str, model: &Model) -> Self {
        let accessors = od_codegen::accessor_names(model);
        let objects: std::collections::BTreeMap<u16, String> = od_codegen::object_names(model).into_iter().collect();
        let mut names: Vec<(String, u16, u8)> = accessors.iter().map(|(i, s, n)| (n.clone(), *i, *s)).collect();
        for (i, s, n) in &accessors {
            if let Some(obj) = objects.get(i) {
                let obj = obj.trim_end_matches('_');
                let rest = n.strip_prefix(obj).and_then(|r| r.strip_prefix('_'));
                match rest {
                    Some(rest) if !rest.is_empty() => names.push((format!("{obj}.{rest}"), *i, *s)),
                    // An entry that took nothing of its object's name: `object.entry`.
                    _ if n != obj => names.push((format!("{obj}.{n}"), *i, *s)),
                    _ => {}
                }
            }
        }
        // The standard names (CiA 301, CiA 402) of the objects the file has, whatever the vendor
        // called them.
        for o in od_codegen::standard::OBJECTS {
            if model.entry(o.index, o.sub).is_some() && !names.iter().any(|(n, _, _)| n == o.name) {
                names.push((o.name.to_owned(), o.index, o.sub));
            }
        }
        Self { file: file.to_owned(), names }
    }

    /// The entry named `name`.
    pub fn find(&self, name: &str) -> Result<(u16, u8, String), ObjectError> {
        let wanted = name.trim().to_ascii_lowercase();
        if let Some((n, i, s)) = self.names.iter().find(|(n, _, _)| *n == wanted) {
            return Ok((*i, *s, n.clone()));
        }
        // A record's (or array's) name: its sub-entries are what was meant.
        let mut suggestions: Vec<String> = Vec::new();
        let dotted = format!("{wanted}.");
        for (n, _, _) in &self.names {
            if n.starts_with(&dotted) && suggestions.len() < 16 {
                suggestions.push(n.clone());
            }
        }
        if !suggestions.is_empty() {
            return Err(ObjectError::UnknownName { name: name.to_owned(), file: self.file.clone(), suggestions });
        }
        let mut scored: Vec<(usize, &str)> =
            self.names.iter().map(|(n, _, _)| (distance(&wanted, n), n.as_str())).collect();
        scored.sort();
        scored.dedup_by(|a, b| a.1 == b.1);
        let limit = wanted.len().max(3) / 2 + 1;
        suggestions = scored.iter().filter(|(d, _)| *d <= limit).take(5).map(|(_, n)| (*n).to_owned()).collect();
        // Names containing the word asked for are close too.
        if suggestions.len() < 5 {
            for (n, _, _) in &self.names {
                if suggestions.len() >= 5 {
                    break;
                }
                if n.contains(&wanted) && !suggestions.contains(n) {
                    suggestions.push(n.clone());
                }
            }
        }
        Err(ObjectError::UnknownName { name: name.to_owned(), file: self.file.clone(), suggestions })
    }

    /// The accessor name of an entry.
    pub fn name_of(&self, index: u16, sub: u8) -> Option<&str> {
        self.names.iter().find(|(_, i, s)| *i == index && *s == sub).map(|(n, _, _)| n.as_str())
    }
}

/// Levenshtein distance, in O(len(a) * len(b)) time and O(len(b)) memory (names are short).
pub fn distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let here = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(here + 1);
            prev = here;
        }
    }
    row[b.len()]
}

/// Resolves an object named on the command line, through `eds` when one is given.
pub fn resolve(text: &str, eds: Option<(&Names, &Model)>) -> Result<Target, ObjectError> {
    if let Some((index, sub)) = parse_numeric(text) {
        let entry = eds.and_then(|(_, m)| m.entry(index, sub));
        let name = eds.and_then(|(n, _)| n.name_of(index, sub)).map(str::to_owned);
        return Ok(Target { index, sub, name, data_type: entry.map(|e| e.data_type), access: entry.map(|e| e.access) });
    }
    let Some((names, model)) = eds else { return Err(ObjectError::Syntax(text.to_owned())) };
    let (index, sub, name) = names.find(text)?;
    let entry = model.entry(index, sub);
    Ok(Target { index, sub, name: Some(name), data_type: entry.map(|e| e.data_type), access: entry.map(|e| e.access) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numeric_forms() {
        assert_eq!(parse_numeric("6041h"), Some((0x6041, 0)));
        assert_eq!(parse_numeric("0x6041"), Some((0x6041, 0)));
        assert_eq!(parse_numeric("1018h:1"), Some((0x1018, 1)));
        assert_eq!(parse_numeric("0x1018:1"), Some((0x1018, 1)));
        assert_eq!(parse_numeric("1018:0x0A"), Some((0x1018, 10)));
        assert_eq!(parse_numeric("1018h:10"), Some((0x1018, 10)));
        assert_eq!(parse_numeric("statusword"), None);
        assert_eq!(parse_numeric("0x10180"), None);
        assert_eq!(parse_numeric("1018h:256"), None);
        assert_eq!(parse_numeric("h"), None);
    }

    #[test]
    fn every_index_and_sub_round_trips_through_each_form() {
        for index in (0..=u16::MAX).step_by(97) {
            for sub in [0u8, 1, 9, 10, 255] {
                for text in [
                    format!("{index:04X}h:{sub}"),
                    format!("0x{index:04x}:{sub}"),
                    format!("{index:X}h:0x{sub:X}"),
                    format!("{index:04X}:{sub:X}h"),
                ] {
                    assert_eq!(parse_numeric(&text), Some((index, sub)), "{text}");
                }
            }
        }
    }

    #[test]
    fn distance_is_edit_distance() {
        assert_eq!(distance("statusword", "statusword"), 0);
        assert_eq!(distance("statusward", "statusword"), 1);
        assert_eq!(distance("", "abc"), 3);
        assert_eq!(distance("kitten", "sitting"), 3);
    }
}

#[cfg(test)]
mod device_names {
    use super::*;

    fn drvi() -> Model {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/camozzi-drvi.eds");
        eds::read_file(path, &eds::Options::lenient()).unwrap().model
    }

    #[test]
    fn the_generated_names_and_object_dot_entry_resolve() {
        let model = drvi();
        let names = Names::new("drvi.eds", &model);
        let eds = Some((&names, &model));
        assert_eq!(resolve("statusword", eds).unwrap().index, 0x6041);
        let vendor = resolve("identity_object.vendor_id", eds).unwrap();
        assert_eq!((vendor.index, vendor.sub), (0x1018, 1));
        // Every accessor the generator gives resolves back to its own entry.
        for (index, sub, name) in od_codegen::accessor_names(&model) {
            let t = resolve(&name, eds).unwrap();
            assert_eq!((t.index, t.sub), (index, sub), "{name}");
        }
    }

    #[test]
    fn an_unknown_name_gets_the_closest_ones() {
        let model = drvi();
        let names = Names::new("drvi.eds", &model);
        let err = resolve("statusward", Some((&names, &model))).unwrap_err();
        let ObjectError::UnknownName { suggestions, .. } = &err else { panic!("{err}") };
        assert_eq!(suggestions.first().map(String::as_str), Some("statusword"), "{err}");
        assert!(matches!(resolve("statusword", None), Err(ObjectError::Syntax(_))));
    }

    #[test]
    fn a_records_name_suggests_its_sub_entries_and_standard_names_resolve() {
        let model = drvi();
        let names = Names::new("drvi.eds", &model);
        let object = od_codegen::object_names(&model).into_iter().find(|(i, _)| *i == 0x1018).unwrap().1;
        let err = resolve(&object, Some((&names, &model))).unwrap_err();
        let ObjectError::UnknownName { suggestions, .. } = &err else { panic!("{err}") };
        assert!(suggestions.len() >= 4, "{err}");
        assert!(suggestions.iter().all(|s| s.starts_with(&format!("{object}."))), "{err}");
        // CiA 301's name of 1018h sub 1, whatever the file calls it.
        let t = resolve("vendor_id", Some((&names, &model))).unwrap();
        assert_eq!((t.index, t.sub), (0x1018, 1));
    }
}
