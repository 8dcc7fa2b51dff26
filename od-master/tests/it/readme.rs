//! The top README's "Control a drive from Rust" example is this crate's README example, which
//! rustdoc compiles as a doc test: the two copies must stay the same.

use std::path::Path;

/// The first ```` ```rust ```` block of a Markdown text, fences included.
fn first_rust_block(text: &str) -> Option<&str> {
    let start = text.find("```rust")?;
    let body = start + text[start..].find('\n')? + 1;
    let end = body + text[body..].find("```")? + 3;
    Some(&text[start..end])
}

#[test]
fn the_top_readme_shows_the_crate_readme_example() {
    let crate_dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let crate_readme = std::fs::read_to_string(crate_dir.join("README.md")).unwrap();
    let top_readme = std::fs::read_to_string(crate_dir.join("../README.md")).unwrap();
    let example = first_rust_block(&crate_readme).expect("od-master/README.md has a Rust example");
    let section = &top_readme[top_readme.find("## Control a drive from Rust").expect("the section")..];
    assert_eq!(first_rust_block(section), Some(example), "README.md's example differs from od-master/README.md's");
    // The issue's limit: an example of 15 lines or fewer.
    assert!(example.lines().count() - 2 <= 15, "{} lines", example.lines().count() - 2);
}
