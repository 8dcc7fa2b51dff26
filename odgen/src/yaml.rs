//! A small streaming JSON → YAML converter for `odgen dump`.
//!
//! Why not a YAML library: `serde_yaml` is deprecated and unmaintained, and its forks are young;
//! the model is plain serde data whose JSON form already exists, so converting JSON *text*
//! (which keeps the model's field order) to block-style YAML takes one small module and no
//! dependency. Every JSON document is valid YAML 1.2 in flow style; this emits block style for
//! readability: mappings as `key: value`, sequences as `- item`, empty ones as `{}`/`[]`, and
//! strings double-quoted (JSON escapes are valid YAML escapes) unless they are plain scalars
//! YAML cannot mistake for something else.
//!
//! The converter reads the JSON as a stream of bytes and writes YAML as it goes, with one byte
//! of look-ahead: it builds no tree, so `odgen dump` holds the model and a few buffers, not the
//! whole document twice over (see [`convert`]).

use std::io::BufRead;

/// Where YAML text goes: `push` appends, and the sink may write out what it has.
pub trait Sink {
    /// Appends text.
    fn push(&mut self, text: &str);
}

impl Sink for String {
    fn push(&mut self, text: &str) {
        self.push_str(text);
    }
}

/// Converts a JSON document to block-style YAML.
#[cfg(test)]
pub fn from_json(json: &str) -> Result<String, String> {
    let mut out = String::new();
    convert(json.as_bytes(), &mut out)?;
    Ok(out)
}

/// Converts the JSON document `input` yields to block-style YAML in `out`, as it reads.
pub fn convert(input: impl BufRead, out: &mut impl Sink) -> Result<(), String> {
    let mut c = Converter { r: input, pos: 0, out };
    c.document_value()?;
    c.ws()?;
    if c.peek()?.is_some() {
        return Err(format!("trailing characters at byte {}", c.pos));
    }
    Ok(())
}

/// What kind of value comes next (for an object or array, its opening bracket is read, and for
/// an empty one its closing bracket too).
enum Next {
    /// A string, number, `true`, `false` or `null` (nothing read yet).
    Scalar,
    /// `{}`.
    EmptyMap,
    /// `[]`.
    EmptySeq,
    /// An object with fields, its `{` read.
    Map,
    /// An array with items, its `[` read.
    Seq,
}

struct Converter<'o, R, S> {
    r: R,
    pos: usize,
    out: &'o mut S,
}

fn indent(out: &mut impl Sink, level: usize) {
    const SPACES: &str = "                                                                ";
    let mut n = level * 2;
    while n > 0 {
        let k = n.min(SPACES.len());
        out.push(&SPACES[..k]);
        n -= k;
    }
}

impl<R: BufRead, S: Sink> Converter<'_, R, S> {
    fn peek(&mut self) -> Result<Option<u8>, String> {
        let buf = self.r.fill_buf().map_err(|e| e.to_string())?;
        Ok(buf.first().copied())
    }

    fn next(&mut self) -> Result<Option<u8>, String> {
        let b = self.peek()?;
        if b.is_some() {
            self.r.consume(1);
            self.pos += 1;
        }
        Ok(b)
    }

    fn ws(&mut self) -> Result<(), String> {
        while matches!(self.peek()?, Some(b' ' | b'\t' | b'\n' | b'\r')) {
            self.next()?;
        }
        Ok(())
    }

    fn eat(&mut self, c: u8) -> Result<(), String> {
        self.ws()?;
        if self.next()? == Some(c) { Ok(()) } else { Err(format!("expected `{}` at byte {}", c as char, self.pos)) }
    }

    /// Which kind of value comes next ([`Next`]).
    fn next_value(&mut self) -> Result<Next, String> {
        self.ws()?;
        let open = match self.peek()? {
            Some(open @ (b'{' | b'[')) => open,
            _ => return Ok(Next::Scalar),
        };
        self.next()?;
        let close = if open == b'{' { b'}' } else { b']' };
        self.ws()?;
        let empty = self.peek()? == Some(close);
        if empty {
            self.next()?;
        }
        Ok(match (open == b'{', empty) {
            (true, true) => Next::EmptyMap,
            (true, false) => Next::Map,
            (false, true) => Next::EmptySeq,
            (false, false) => Next::Seq,
        })
    }

    /// The document's one value, at the left margin.
    fn document_value(&mut self) -> Result<(), String> {
        match self.next_value()? {
            Next::EmptyMap => self.out.push("{}\n"),
            Next::EmptySeq => self.out.push("[]\n"),
            Next::Map => return self.map_body(0),
            Next::Seq => return self.seq_body(0),
            Next::Scalar => {
                let s = self.scalar()?;
                self.out.push(&s);
                self.out.push("\n");
            }
        }
        Ok(())
    }

    /// The fields of a non-empty object whose `{` was read, at `level`; reads the `}`.
    fn map_body(&mut self, level: usize) -> Result<(), String> {
        let mut first = true;
        loop {
            if !first {
                indent(self.out, level);
            }
            self.field(level)?;
            first = false;
            self.ws()?;
            match self.next()? {
                Some(b',') => {}
                Some(b'}') => return Ok(()),
                _ => return Err(format!("expected `,` or `}}` at byte {}", self.pos)),
            }
        }
    }

    /// One `key: value` whose indentation is written.
    fn field(&mut self, level: usize) -> Result<(), String> {
        self.ws()?;
        let key = self.string()?;
        self.out.push(&string_text(&key));
        self.out.push(":");
        self.eat(b':')?;
        self.value_after_key(level)
    }

    /// A value after `key:`: on the key's line when it is a scalar or empty, otherwise on the
    /// next lines at `level + 1`.
    fn value_after_key(&mut self, level: usize) -> Result<(), String> {
        match self.next_value()? {
            Next::EmptyMap => self.out.push(" {}\n"),
            Next::EmptySeq => self.out.push(" []\n"),
            next @ (Next::Map | Next::Seq) => {
                self.out.push("\n");
                indent(self.out, level + 1);
                return if matches!(next, Next::Map) { self.map_body(level + 1) } else { self.seq_body(level + 1) };
            }
            Next::Scalar => self.scalar_on_line()?,
        }
        Ok(())
    }

    /// The items of a non-empty array whose `[` was read, at `level` (the first item's
    /// indentation is written); reads the `]`.
    fn seq_body(&mut self, level: usize) -> Result<(), String> {
        let mut first = true;
        loop {
            if !first {
                indent(self.out, level);
            }
            first = false;
            self.out.push("-");
            self.item(level)?;
            self.ws()?;
            match self.next()? {
                Some(b',') => {}
                Some(b']') => return Ok(()),
                _ => return Err(format!("expected `,` or `]` at byte {}", self.pos)),
            }
        }
    }

    /// An array item after its `-`: an object's first field on the dash line and the rest
    /// aligned under it, an array on the next lines, anything else on the dash line.
    fn item(&mut self, level: usize) -> Result<(), String> {
        match self.next_value()? {
            Next::EmptyMap => self.out.push(" {}\n"),
            Next::EmptySeq => self.out.push(" []\n"),
            Next::Map => {
                self.out.push(" ");
                self.map_body(level + 1)?;
            }
            Next::Seq => {
                self.out.push("\n");
                indent(self.out, level + 1);
                self.seq_body(level + 1)?;
            }
            Next::Scalar => self.scalar_on_line()?,
        }
        Ok(())
    }

    /// A scalar on the line written so far: ` value` and the line's end.
    fn scalar_on_line(&mut self) -> Result<(), String> {
        let s = self.scalar()?;
        self.out.push(" ");
        self.out.push(&s);
        self.out.push("\n");
        Ok(())
    }

    /// A string, number, `true`, `false` or `null`, as YAML text.
    fn scalar(&mut self) -> Result<String, String> {
        self.ws()?;
        match self.peek()? {
            None => Err("unexpected end of JSON".to_owned()),
            Some(b'"') => Ok(string_text(&self.string()?)),
            Some(b't') => self.word("true"),
            Some(b'f') => self.word("false"),
            Some(b'n') => self.word("null"),
            Some(_) => {
                let mut n = String::new();
                while let Some(b @ (b'-' | b'+' | b'.' | b'e' | b'E' | b'0'..=b'9')) = self.peek()? {
                    n.push(b as char);
                    self.next()?;
                }
                if n.is_empty() {
                    return Err(format!("unexpected character at byte {}", self.pos));
                }
                Ok(n)
            }
        }
    }

    fn word(&mut self, w: &str) -> Result<String, String> {
        for &b in w.as_bytes() {
            if self.next()? != Some(b) {
                return Err(format!("unexpected word at byte {}", self.pos));
            }
        }
        Ok(w.to_owned())
    }

    /// A JSON string, decoded.
    fn string(&mut self) -> Result<String, String> {
        if self.next()? != Some(b'"') {
            return Err(format!("expected a string at byte {}", self.pos));
        }
        let mut raw = vec![b'"'];
        loop {
            // Whole runs without `"` or `\` at a time.
            let buf = self.r.fill_buf().map_err(|e| e.to_string())?;
            if buf.is_empty() {
                return Err("unterminated string".to_owned());
            }
            let len = buf.len();
            let run = buf.iter().position(|&b| b == b'"' || b == b'\\').unwrap_or(len);
            raw.extend_from_slice(&buf[..run]);
            self.r.consume(run);
            self.pos += run;
            if run == len {
                continue; // the string goes on in the next block
            }
            match self.next()? {
                Some(b'"') => break,
                Some(b'\\') => {
                    raw.push(b'\\');
                    let e = self.next()?.ok_or("unterminated string")?;
                    raw.push(e);
                }
                _ => {}
            }
        }
        raw.push(b'"');
        if !raw.contains(&b'\\') {
            return String::from_utf8(raw[1..raw.len() - 1].to_vec()).map_err(|e| e.to_string());
        }
        serde_json::from_slice::<String>(&raw).map_err(|e| e.to_string())
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
    fn nested_sequences_and_maps_in_sequences() {
        let y = from_json(r#"[[1, [2, 3]], {"a": [{"b": {}}, []]}, [], {}]"#).unwrap();
        assert_eq!(y, "-\n  - 1\n  -\n    - 2\n    - 3\n- a:\n    - b: {}\n    - []\n- []\n- {}\n");
    }

    /// Strings longer than the reader's block, with escapes at every place relative to the
    /// block's end, come through whole.
    #[test]
    fn strings_across_blocks() {
        for len in [7, 8, 9, 15, 16, 17, 100] {
            let long: String = (0..len).map(|i| if i % 5 == 0 { '"' } else { 'x' }).collect();
            let json = serde_json::to_string(&vec![long.clone(), "b".repeat(len)]).unwrap();
            let mut out = String::new();
            convert(std::io::BufReader::with_capacity(8, json.as_bytes()), &mut out).unwrap();
            assert_eq!(out, format!("- {}\n- {}\n", string_text(&long), "b".repeat(len)), "{len}");
        }
    }

    #[test]
    fn escapes_survive() {
        let y = from_json(r#"{"a": "line\nbreak \"q\" \u00e9"}"#).unwrap();
        assert_eq!(y, "a: \"line\\nbreak \\\"q\\\" é\"\n");
        assert!(from_json("{").is_err());
        assert!(from_json(r#"{"a": 1} x"#).is_err());
        assert_eq!(from_json("[]").unwrap(), "[]\n");
        assert_eq!(from_json("5").unwrap(), "5\n");
    }
}
