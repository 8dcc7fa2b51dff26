//! `eds::parse` on any bytes, in both modes: no panic, and every diagnostic renders and
//! serialises.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    for options in [eds::Options::lenient(), eds::Options::strict()] {
        let parsed = eds::parse("fuzz.eds", data, &options);
        let mut out = String::new();
        for d in &parsed.diagnostics {
            eds::diag::render_to(&mut out, d, &parsed.document.source);
            eds::diag::push_json(&mut out, d);
            out.clear();
        }
    }
});
