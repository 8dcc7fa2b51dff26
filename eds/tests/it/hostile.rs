//! Hostile input: files shaped to make a reader slow, large or wrong (an outside robustness run
//! found each of these). The rules tested here hold for every input of the kind, so the inputs
//! are built in the tests.

use std::path::{Path, PathBuf};

use eds::{Options, Severity};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// Every fixture (the base file and one per diagnostic code) as text.
fn fixture_texts() -> Vec<(String, String)> {
    let mut out = vec![("base.eds".to_owned(), std::fs::read_to_string(fixtures().join("base.eds")).unwrap())];
    let mut diag: Vec<_> = std::fs::read_dir(fixtures().join("diag")).unwrap().map(|e| e.unwrap().path()).collect();
    diag.sort();
    for p in diag {
        let bytes = std::fs::read(&p).unwrap();
        // (E0001 is not UTF-8 on purpose; it is about the encoding, not the line ends.)
        if let Ok(text) = String::from_utf8(bytes) {
            out.push((p.file_name().unwrap().to_string_lossy().into_owned(), text));
        }
    }
    out
}

/// Diagnostics as (code, severity, line, column, message).
fn located(p: &eds::Parsed) -> Vec<(eds::Code, Severity, u32, u32, String)> {
    p.diagnostics
        .iter()
        .map(|d| (d.code, d.severity, d.at.map_or(0, |a| a.line), d.at.map_or(0, |a| a.col), d.message.clone()))
        .collect()
}

/// A lone `\r` ends a line for positions as it does for the lexer: a file with its `\n`s
/// replaced by `\r` or `\r\n` gets every diagnostic at the same line and column.
#[test]
fn every_line_end_gives_the_same_positions() {
    for (name, text) in fixture_texts() {
        let lf = text.replace("\r\n", "\n");
        let want = located(&eds::parse(&name, lf.as_bytes(), &Options::strict()));
        for ending in ["\r", "\r\n"] {
            let other = lf.replace('\n', ending);
            let got = located(&eds::parse(&name, other.as_bytes(), &Options::strict()));
            assert_eq!(got, want, "{name} with {ending:?} line ends");
        }
    }
}

/// The longest line of a rendered diagnostic, in characters.
fn longest_line(text: &str) -> usize {
    text.lines().map(|l| l.chars().count()).max().unwrap_or(0)
}

/// A rendered diagnostic quotes at most a window of its line, however long the line (a file
/// with one 120 KB line used to be quoted whole for every diagnostic on it).
#[test]
fn quoted_lines_are_cut() {
    // One very long line, with problems at its start, middle and end.
    let mut text = String::from("[FileInfo]\n");
    text.push_str(&"Junk without an equals sign ".repeat(2000));
    text.push_str("\n[1000]\nParameterName=Device type\nObjectType=0x7\nDataType=0x0007\nAccessType=ro\nDefaultValue=");
    text.push_str(&"9".repeat(5000));
    text.push('\n');
    let parsed = eds::parse("long.eds", text.as_bytes(), &Options::strict());
    assert!(!parsed.diagnostics.is_empty());
    for d in &parsed.diagnostics {
        let out = eds::diag::render(d, &parsed.document.source);
        assert!(longest_line(&out) <= eds::diag::MAX_QUOTED as usize + 300, "{out}");
        if d.span.is_some() && out.contains("DefaultValue=999") {
            assert!(out.contains('…'), "{out}");
        }
    }
}

/// A window cut out of a long line still has its caret under the span.
#[test]
fn caret_under_the_span_in_a_cut_line() {
    let line = format!("K={}BAD{}", "x".repeat(1000), "y".repeat(1000));
    let src = eds::source::SourceFile::from_str("a.eds", format!("{line}\n"));
    let start = line.find("BAD").unwrap() as u32;
    let mut d = eds::Diagnostic::new(eds::codes::E0301, eds::Strictness::Strict, "a.eds", "bad");
    d.span = Some(eds::source::Span::new(start, start + 3));
    d.at = Some(src.line_col(start));
    let out = eds::diag::render(&d, &src);
    let lines: Vec<&str> = out.lines().collect();
    let quoted = lines[3].split_once(" | ").unwrap().1;
    let carets = lines[4].split_once(" | ").unwrap().1;
    let at = carets.find('^').unwrap();
    let chars: Vec<char> = quoted.chars().collect();
    assert_eq!(chars[at..at + 3].iter().collect::<String>(), "BAD", "{out}");
    assert!(quoted.starts_with('…') && quoted.ends_with('…'), "{out}");
    assert!(chars.len() <= eds::diag::MAX_QUOTED as usize + 2);
}

/// A CR-only file of many problems renders in output proportional to its problems, not to
/// the file size times the problems.
#[test]
fn cr_only_file_renders_small() {
    let mut text = String::from("[FileInfo]\r");
    for i in 0..3000 {
        text.push_str(&format!("junk line {i}\r"));
    }
    let parsed = eds::parse("cr.eds", text.as_bytes(), &Options::lenient());
    let junk: Vec<_> = parsed.diagnostics.iter().filter(|d| d.code == eds::codes::E0002).collect();
    assert_eq!(junk.len(), 3000);
    for (i, d) in junk.iter().enumerate() {
        assert_eq!(d.at.map(|a| a.line), Some(i as u32 + 2));
    }
    let rendered: usize = parsed.diagnostics.iter().map(|d| eds::diag::render(d, &parsed.document.source).len()).sum();
    assert!(rendered < 3000 * 400, "{rendered} bytes of diagnostics");
}

/// `n` sections of distinct unknown names (`[Foo0]`, `[Foo1]`, …; every tenth spelled again in
/// other case later, which merges it into the first).
fn unknown_sections(n: usize) -> String {
    let mut text = std::fs::read_to_string(fixtures().join("base.eds")).unwrap();
    for i in 0..n {
        text.push_str(&format!("[Foo{i}]\nKey{i}=v\n"));
    }
    for i in (0..n).step_by(10) {
        text.push_str(&format!("[FOO{i}]\nOther=w\n"));
    }
    text
}

/// Grouping sections costs a bounded number of name comparisons per section header, however
/// many distinct unknown sections there are (each header was compared with every unknown
/// section before it: 20k sections took 0.7 s, 80k 15 s). Counted, not timed.
#[test]
fn unknown_sections_are_grouped_in_linear_work() {
    if cfg!(not(debug_assertions)) {
        return; // release builds do not count
    }
    for n in [5_000, 20_000, 80_000] {
        let text = unknown_sections(n);
        let before = eds::lower::name_comparisons();
        let parsed = eds::parse("unknown.eds", text.as_bytes(), &Options::lenient());
        let comparisons = eds::lower::name_comparisons() - before;
        assert_eq!(parsed.model.extra_sections.len(), n);
        let repeated = parsed.diagnostics.iter().filter(|d| d.code == eds::codes::E0006).count();
        assert_eq!(repeated, n / 10);
        // A few per header at most (a scan of the sections before it made n²/2).
        let headers = (n + n / 10) as u64;
        assert!(comparisons <= 3 * headers, "{n} sections: {comparisons} comparisons");
    }
}

/// A UTF-16 file (either byte order, with its byte-order mark) reads as the same file saved as
/// UTF-8: the same model and the same diagnostics at the same places, plus E0010 saying it is
/// UTF-16; and it is written back byte for byte. (It was read as Windows-1252: 1,768 warnings,
/// and `fmt` wrote a 144-byte skeleton.)
#[test]
fn utf16_reads_as_its_utf8_twin() {
    for (name, text) in fixture_texts() {
        let utf8 = eds::parse(&name, text.as_bytes(), &Options::strict());
        for (bom, little) in [([0xFF, 0xFE], true), ([0xFE, 0xFF], false)] {
            let mut bytes = bom.to_vec();
            for u in text.encode_utf16() {
                bytes.extend(if little { u.to_le_bytes() } else { u.to_be_bytes() });
            }
            let utf16 = eds::parse(&name, &bytes, &Options::strict());
            assert_eq!(utf16.model, utf8.model, "{name}");
            let mut want = located(&utf8);
            // (E0009, non-ASCII text, is about UTF-8 files; E0010 says the encoding instead.)
            want.retain(|d| d.0 != eds::codes::E0009);
            let mut got = located(&utf16);
            assert_eq!(got.iter().filter(|d| d.0 == eds::codes::E0010).count(), 1, "{name}");
            got.retain(|d| d.0 != eds::codes::E0010);
            assert_eq!(got, want, "{name}");
            assert_eq!(utf16.document.write_lossless(), bytes, "{name}");
        }
    }
}

/// The sections of a text: (header line, body).
fn sections_of(text: &str) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for line in text.lines() {
        if line.starts_with('[') || out.is_empty() {
            out.push(String::new());
        }
        let last = out.last_mut().unwrap();
        last.push_str(line);
        last.push('\n');
    }
    out
}

/// A section given twice (every key set in both, some to other values, plus a key only the
/// repeat has) is one section in the model, each key once with its later value: the canonical
/// text written from it has no repeated section or key, and reads back as the same model.
/// (`fmt` turned each repeated section into repeated keys: 37 warnings became 396.)
#[test]
fn repeated_sections_are_written_once() {
    // (E0222's model stops at the file's bound of implicit elements, which depends on the
    // file's size: it is not the file's model, and `fmt` refuses it.)
    for (name, text) in fixture_texts().into_iter().filter(|(name, _)| name != "E0222.eds") {
        let sections = sections_of(&text);
        let mut doubled = text.clone();
        for (i, sec) in sections.iter().enumerate().filter(|(_, s)| s.starts_with('[')) {
            let changed = sec.replace("=0\n", "=1\n");
            doubled.push_str(&format!("\n{changed}ExtraKeyOfRepeat{i}=x\n"));
        }
        let parsed = eds::parse(&name, doubled.as_bytes(), &Options::lenient());
        let written = eds::write::write(&parsed.model);
        let back = eds::parse(&name, written.as_bytes(), &Options::lenient());
        let repeats: Vec<_> = back
            .diagnostics
            .iter()
            .filter(|d| d.code == eds::codes::E0006 || d.code == eds::codes::E0007)
            .map(|d| d.message.clone())
            .collect();
        assert!(repeats.is_empty(), "{name}: {repeats:#?}");
        assert_eq!(back.model, parsed.model, "{name}");
    }
}

/// The JSON written directly for each diagnostic is what serde makes of it (`to_json`), for
/// every diagnostic of every fixture, and for text with every control character and quotes.
#[test]
fn direct_json_equals_serde_json() {
    let mut texts = fixture_texts();
    let odd: String = (0u8..0x80).map(char::from).chain("\"\\ äß€ \u{1F600}".chars()).collect();
    texts.push(("odd.eds".into(), format!("[FileInfo]\n{odd}\nKey{odd}=1\n[Section{odd}]\n")));
    for (name, text) in texts {
        let parsed = eds::parse(&name, text.as_bytes(), &Options::strict());
        let want: serde_json::Value = serde_json::from_str(&eds::diag::to_json(&parsed.diagnostics)).unwrap();
        let mut direct = String::from("[");
        for (i, d) in parsed.diagnostics.iter().enumerate() {
            if i > 0 {
                direct.push(',');
            }
            eds::diag::push_json(&mut direct, d);
        }
        direct.push(']');
        let got: serde_json::Value = serde_json::from_str(&direct).unwrap_or_else(|e| panic!("{name}: {e}: {direct}"));
        assert_eq!(got, want, "{name}");
    }
}

/// E0219 (ARRAY elements of different types; an error under --strict) is located in every
/// shape of ARRAY: elements in sections, CompactSubObj elements with sub 1 or a later one
/// overridden. (With sub 1 overridden the differing element had no section, and the
/// diagnostic no line.)
#[test]
fn mixed_array_types_are_located() {
    let base = std::fs::read_to_string(fixtures().join("base.eds")).unwrap();
    let sub = |n: u8, dt: &str| {
        format!(
            "[2100sub{n:X}]\nParameterName=e{n}\nObjectType=0x7\nDataType={dt}\nAccessType=rw\nDefaultValue=0\nPDOMapping=0\n\n"
        )
    };
    let head = "[2100]\nParameterName=Mixed\nObjectType=0x8\n";
    let compact = "DataType=0x0006\nAccessType=rw\nCompactSubObj=4\nPDOMapping=0\n\n";
    let shapes = [
        format!("{head}SubNumber=3\n\n{}{}{}", sub(0, "0x0005"), sub(1, "0x0006"), sub(2, "0x0007")),
        format!("{head}{compact}{}", sub(1, "0x0007")),
        format!("{head}{compact}{}", sub(3, "0x0007")),
    ];
    for shape in shapes {
        let text = base
            .replace("SupportedObjects=2\n1=0x2000\n2=0x2001\n", "SupportedObjects=3\n1=0x2000\n2=0x2001\n3=0x2100\n")
            + "\n"
            + &shape;
        let parsed = eds::parse("mixed.eds", text.as_bytes(), &Options::strict());
        let mixed: Vec<_> = parsed.diagnostics.iter().filter(|d| d.code == eds::codes::E0219).collect();
        assert_eq!(mixed.len(), 1, "{shape}\n{:#?}", parsed.diagnostics);
        assert_eq!(mixed[0].severity, Severity::Error);
        let at = mixed[0].at.unwrap_or_else(|| panic!("E0219 without a place:\n{shape}"));
        let line = parsed.document.source.line_text(at.line);
        assert!(line.starts_with("[2100"), "{line}");
    }
}

/// A file of a great many problems keeps at most `MAX_PER_CODE` diagnostics of a code (and
/// says how many more there were): memory for diagnostics stays bounded whatever the file (700k
/// junk lines kept 700k diagnostics, a hundred times the input).
#[test]
fn diagnostics_of_one_code_are_bounded() {
    let n = 3 * eds::lower::MAX_PER_CODE as usize;
    let mut text = std::fs::read_to_string(fixtures().join("base.eds")).unwrap();
    text.push_str("[Tools]\n");
    for i in 0..n {
        text.push_str(&format!("junk{i}\n"));
    }
    let parsed = eds::parse("junk.eds", text.as_bytes(), &Options::lenient());
    let junk: Vec<_> = parsed.diagnostics.iter().filter(|d| d.code == eds::codes::E0002).collect();
    assert_eq!(junk.len(), eds::lower::MAX_PER_CODE as usize + 1);
    let last = junk.last().unwrap();
    assert!(last.span.is_none());
    let left = n - eds::lower::MAX_PER_CODE as usize;
    assert!(last.message.starts_with(&format!("{left} more E0002 diagnostics")), "{}", last.message);
    // The kept ones are the first, in order.
    assert_eq!(junk[0].at.map(|a| a.line), Some(text.lines().position(|l| l == "junk0").unwrap() as u32 + 1));
    // Other codes are still reported.
    assert!(parsed.diagnostics.iter().any(|d| d.code == eds::codes::E0101));
}

/// `parse_owned` (what `read_file` uses) reads every input as `parse` does: UTF-8 with and
/// without a mark, UTF-16, Windows-1252.
#[test]
fn parse_owned_agrees_with_parse() {
    for (name, text) in fixture_texts() {
        let utf16: Vec<u8> = [0xFF, 0xFE].into_iter().chain(text.encode_utf16().flat_map(u16::to_le_bytes)).collect();
        let marked: Vec<u8> = b"\xEF\xBB\xBF".iter().copied().chain(text.bytes()).collect();
        let cp1252: Vec<u8> = text.bytes().chain([0x94, b'\n']).collect();
        for bytes in [text.clone().into_bytes(), utf16, marked, cp1252] {
            let a = eds::parse(&name, &bytes, &Options::strict());
            let b = eds::parse_owned(&name, bytes.clone(), &Options::strict());
            assert_eq!(a.model, b.model, "{name}");
            assert_eq!(a.diagnostics, b.diagnostics, "{name}");
            assert_eq!(b.document.write_lossless(), bytes, "{name}");
        }
    }
}

/// Implicit CompactSubObj elements are bounded by the file's size (`implicit_budget`): a file
/// that declares more gets one E0222 and a model within the bound, whatever the number of
/// arrays; a file within the bound gets every element. (7,500 arrays of `CompactSubObj=255`,
/// 0.78 MB, were a model of 1.9 million entries, 230 MB.)
#[test]
fn implicit_elements_are_bounded_by_the_file_size() {
    let base = std::fs::read_to_string(fixtures().join("base.eds")).unwrap();
    let arrays = |n: usize, each: u8| -> String {
        let mut t = base.clone();
        for i in 0..n {
            t.push_str(&format!(
                "\n[{:04X}]\nParameterName=A{i}\nObjectType=0x8\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\n\
                 CompactSubObj={each}\nPDOMapping=0\n",
                0x3000 + i
            ));
        }
        t
    };
    let entries = |m: &eds::model::Model| m.objects.values().map(|o| o.subs.len()).sum::<usize>();
    let in_base = entries(&eds::parse("base.eds", base.as_bytes(), &Options::lenient()).model);
    for n in [100, 257, 300, 1_000, 7_500] {
        let text = arrays(n, 254);
        let p = eds::parse("a.eds", text.as_bytes(), &Options::lenient());
        let budget = eds::lower::implicit_budget(text.len());
        let e0222 = p.diagnostics.iter().filter(|d| d.code == eds::codes::E0222).count();
        let declared = n * 254;
        assert_eq!(e0222, usize::from(declared > budget), "{n} arrays");
        // Every array keeps sub-index 0; the elements stay within the bound.
        let implicit = entries(&p.model) - in_base - n;
        assert!(implicit <= budget, "{n} arrays: {implicit} elements, bound {budget}");
        if declared <= budget {
            assert_eq!(implicit, declared, "{n} arrays");
        } else {
            // Up to the array that crosses the bound, every array is whole.
            assert!(implicit + 254 > budget, "{n} arrays: {implicit} elements, bound {budget}");
            assert!(p.has_errors());
        }
    }
    // Many small arrays (2 elements each) stay within the bound of their size and are whole.
    let text = arrays(7_500, 2);
    let p = eds::parse("a.eds", text.as_bytes(), &Options::lenient());
    assert!(p.diagnostics.iter().all(|d| d.code != eds::codes::E0222));
}

/// A file larger than positions can say (4 GiB) is refused before it is read, with its size
/// (the file is sparse: no disk is written, and nothing is read).
#[test]
fn a_file_of_4_gib_or_more_is_refused_unread() {
    let dir = std::env::temp_dir().join(format!("eds-huge-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("huge.eds");
    let file = std::fs::File::create(&path).expect("create");
    if file.set_len(eds::MAX_FILE + 1).is_err() {
        // (A file system without sparse files of that size: nothing to check here.)
        let _ = std::fs::remove_dir_all(&dir);
        return;
    }
    drop(file);
    let started = std::time::Instant::now();
    let refused = eds::read_file(&path, &eds::Options::lenient()).expect_err("refused");
    let reader = eds::Reader::new().read_file(&path, &eds::Options::lenient()).expect_err("refused");
    let _ = std::fs::remove_dir_all(&dir);
    assert_eq!(refused.kind(), std::io::ErrorKind::InvalidData);
    assert!(refused.to_string().contains(&format!("{} bytes", eds::MAX_FILE + 1)), "{refused}");
    assert_eq!(reader.to_string(), refused.to_string());
    // (Reading 4 GiB would take seconds and as much memory.)
    assert!(started.elapsed() < std::time::Duration::from_secs(2));
}
