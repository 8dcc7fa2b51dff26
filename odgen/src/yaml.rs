//! A small JSON-text → YAML converter for `odgen dump`.
//!
//! Why not a YAML library: `serde_yaml` is deprecated and unmaintained, and its forks are young;
//! the model is plain serde data whose JSON form already exists, so converting JSON *text*
//! (which keeps the model's field order, unlike `serde_json::Value` without `preserve_order`)
//! to block-style YAML takes one small module and no dependency. Every JSON document is valid
//! YAML 1.2 in flow style; this emits block style for readability: mappings as `key: value`,
//! sequences as `- item`, empty ones as `{}`/`[]`, and strings double-quoted (JSON escapes are
//! valid YAML escapes) unless they are plain scalars YAML cannot mistake for something else.

use std::fmt::Write as _;

/// A parsed JSON value that keeps object keys in document order.
#[derive(Debug, PartialEq)]
enum Node {
    Null,
    Bool(bool),
    /// A number, as written (JSON and YAML number syntax agree for what serde_json writes).
    Number(String),
    String(String),
    Array(Vec<Node>),
    Object(Vec<(String, Node)>),
}

/// Converts a JSON document to block-style YAML.
pub fn from_json(json: &str) -> Result<String, String> {
    let mut p = Parser { s: json.as_bytes(), i: 0 };
    let node = p.value()?;
    p.ws();
    if p.i != p.s.len() {
        return Err(format!("trailing characters at byte {}", p.i));
    }
    let mut out = String::new();
    match &node {
        Node::Array(items) if !items.is_empty() => emit_seq(&mut out, items, 0),
        Node::Object(fields) if !fields.is_empty() => emit_map(&mut out, fields, 0),
        scalar => {
            out.push_str(&scalar_text(scalar));
            out.push('\n');
        }
    }
    Ok(out)
}

struct Parser<'a> {
    s: &'a [u8],
    i: usize,
}

impl Parser<'_> {
    fn ws(&mut self) {
        while self.i < self.s.len() && matches!(self.s[self.i], b' ' | b'\t' | b'\n' | b'\r') {
            self.i += 1;
        }
    }

    fn eat(&mut self, c: u8) -> Result<(), String> {
        self.ws();
        if self.s.get(self.i) == Some(&c) {
            self.i += 1;
            Ok(())
        } else {
            Err(format!("expected `{}` at byte {}", c as char, self.i))
        }
    }

    fn value(&mut self) -> Result<Node, String> {
        self.ws();
        match self.s.get(self.i) {
            None => Err("unexpected end of JSON".to_owned()),
            Some(b'{') => {
                self.i += 1;
                let mut fields = Vec::new();
                self.ws();
                if self.s.get(self.i) == Some(&b'}') {
                    self.i += 1;
                    return Ok(Node::Object(fields));
                }
                loop {
                    self.ws();
                    let key = self.string()?;
                    self.eat(b':')?;
                    let v = self.value()?;
                    fields.push((key, v));
                    self.ws();
                    match self.s.get(self.i) {
                        Some(b',') => self.i += 1,
                        Some(b'}') => {
                            self.i += 1;
                            return Ok(Node::Object(fields));
                        }
                        _ => return Err(format!("expected `,` or `}}` at byte {}", self.i)),
                    }
                }
            }
            Some(b'[') => {
                self.i += 1;
                let mut items = Vec::new();
                self.ws();
                if self.s.get(self.i) == Some(&b']') {
                    self.i += 1;
                    return Ok(Node::Array(items));
                }
                loop {
                    items.push(self.value()?);
                    self.ws();
                    match self.s.get(self.i) {
                        Some(b',') => self.i += 1,
                        Some(b']') => {
                            self.i += 1;
                            return Ok(Node::Array(items));
                        }
                        _ => return Err(format!("expected `,` or `]` at byte {}", self.i)),
                    }
                }
            }
            Some(b'"') => Ok(Node::String(self.string()?)),
            Some(b't') => self.word("true", Node::Bool(true)),
            Some(b'f') => self.word("false", Node::Bool(false)),
            Some(b'n') => self.word("null", Node::Null),
            Some(_) => {
                let start = self.i;
                while self.i < self.s.len() && matches!(self.s[self.i], b'-' | b'+' | b'.' | b'e' | b'E' | b'0'..=b'9')
                {
                    self.i += 1;
                }
                if start == self.i {
                    return Err(format!("unexpected character at byte {start}"));
                }
                Ok(Node::Number(String::from_utf8_lossy(&self.s[start..self.i]).into_owned()))
            }
        }
    }

    fn word(&mut self, w: &str, node: Node) -> Result<Node, String> {
        if self.s[self.i..].starts_with(w.as_bytes()) {
            self.i += w.len();
            Ok(node)
        } else {
            Err(format!("unexpected word at byte {}", self.i))
        }
    }

    fn string(&mut self) -> Result<String, String> {
        if self.s.get(self.i) != Some(&b'"') {
            return Err(format!("expected a string at byte {}", self.i));
        }
        let start = self.i;
        self.i += 1;
        while self.i < self.s.len() {
            match self.s[self.i] {
                b'\\' => self.i += 2,
                b'"' => {
                    self.i += 1;
                    let raw = std::str::from_utf8(&self.s[start..self.i]).map_err(|e| e.to_string())?;
                    return serde_json::from_str::<String>(raw).map_err(|e| e.to_string());
                }
                _ => self.i += 1,
            }
        }
        Err("unterminated string".to_owned())
    }
}

fn indent(out: &mut String, level: usize) {
    for _ in 0..level {
        out.push_str("  ");
    }
}

fn is_block(node: &Node) -> bool {
    matches!(node, Node::Array(a) if !a.is_empty()) || matches!(node, Node::Object(o) if !o.is_empty())
}

fn emit_map(out: &mut String, fields: &[(String, Node)], level: usize) {
    for (k, v) in fields {
        indent(out, level);
        out.push_str(&string_text(k));
        out.push(':');
        emit_after_key(out, v, level);
    }
}

fn emit_after_key(out: &mut String, v: &Node, level: usize) {
    match v {
        Node::Object(f) if !f.is_empty() => {
            out.push('\n');
            emit_map(out, f, level + 1);
        }
        Node::Array(items) if !items.is_empty() => {
            out.push('\n');
            emit_seq(out, items, level + 1);
        }
        scalar => {
            out.push(' ');
            out.push_str(&scalar_text(scalar));
            out.push('\n');
        }
    }
}

fn emit_seq(out: &mut String, items: &[Node], level: usize) {
    for item in items {
        indent(out, level);
        out.push('-');
        match item {
            Node::Object(f) if !f.is_empty() => {
                // First field on the dash line, the rest aligned under it.
                let (k, v) = &f[0];
                let _ = write!(out, " {}:", string_text(k));
                emit_after_key(out, v, level + 1);
                emit_map(out, &f[1..], level + 1);
            }
            Node::Array(inner) if !inner.is_empty() => {
                out.push('\n');
                emit_seq(out, inner, level + 1);
            }
            scalar => {
                debug_assert!(!is_block(scalar));
                out.push(' ');
                out.push_str(&scalar_text(scalar));
                out.push('\n');
            }
        }
    }
}

fn scalar_text(node: &Node) -> String {
    match node {
        Node::Null => "null".to_owned(),
        Node::Bool(b) => b.to_string(),
        Node::Number(n) => n.clone(),
        Node::String(s) => string_text(s),
        Node::Array(_) => "[]".to_owned(),
        Node::Object(_) => "{}".to_owned(),
    }
}

/// A string as a YAML scalar: plain when that is unambiguous, else JSON-quoted.
fn string_text(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.' | ' ' | '/' | '(' | ')'))
        && s.starts_with(|c: char| c.is_ascii_alphabetic() || c == '_')
        && !s.ends_with(' ')
        && !matches!(
            s.to_ascii_lowercase().as_str(),
            "true" | "false" | "yes" | "no" | "on" | "off" | "null" | "y" | "n" | "nan" | "inf"
        );
    if plain { s.to_owned() } else { serde_json::to_string(s).unwrap_or_else(|_| "\"\"".to_owned()) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn block_style_keeps_order_and_quotes_what_needs_it() {
        let json = r#"{"z": 1, "a": {"list": [1, {"k": "v", "n": null}], "empty": [], "e2": {}},
            "s": "needs: quoting", "t": "true", "num": "0x10", "plain": "Device type", "neg": -5}"#;
        let y = from_json(json).unwrap();
        assert_eq!(
            y,
            "z: 1\na:\n  list:\n    - 1\n    - k: v\n      \"n\": null\n  empty: []\n  e2: {}\n\
             s: \"needs: quoting\"\nt: \"true\"\nnum: \"0x10\"\nplain: Device type\nneg: -5\n"
        );
    }

    #[test]
    fn escapes_survive() {
        let y = from_json(r#"{"a": "line\nbreak \"q\" \u00e9"}"#).unwrap();
        assert_eq!(y, "a: \"line\\nbreak \\\"q\\\" é\"\n");
        assert!(from_json("{").is_err());
        assert!(from_json(r#"{"a": 1} x"#).is_err());
        assert_eq!(from_json("[]").unwrap(), "[]\n");
    }
}
