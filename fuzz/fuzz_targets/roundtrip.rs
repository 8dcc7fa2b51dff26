//! parse → write → parse: a file without errors whose model the writer can represent reads back
//! as the same model, and its canonical text is a fixed point (what `odgen fmt` relies on).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let options = eds::Options::lenient();
    let parsed = eds::parse("fuzz.eds", data, &options);
    if parsed.has_errors() || !eds::write::unrepresentable(&parsed.model).is_empty() {
        return;
    }
    let text = eds::write::write(&parsed.model);
    let back = eds::parse("fuzz.eds", text.as_bytes(), &options);
    assert!(!back.has_errors(), "the canonical text has errors");
    assert!(back.model == parsed.model, "the canonical text reads back as another model");
    assert_eq!(eds::write::write(&back.model), text, "the canonical text is not a fixed point");
});
