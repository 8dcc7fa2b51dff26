//! CPU time of each phase of generating one description, as a build script would (run it in
//! the dev profile, which is what a build script gets without `build-override` settings):
//!
//! ```text
//! cargo run -p od-codegen --example gen_time -- FILE [ROUNDS]
//! ```
//!
//! Times the calls `Builder` (and so `odgen gen`) makes, and only those: reading
//! (`eds::parse`), planning and emitting (`od_codegen::expand_text`: the large parts written as
//! text, the rest as tokens), and rendering (`GeneratedText::render`: syn and prettyplease on
//! the rest, the text spliced in). Prints the process CPU time (user + system, from
//! `/proc/self/stat`, so a loaded machine's waiting is not counted) of each, best of ROUNDS
//! (default 3), and the size of the file.

fn cpu_seconds() -> f64 {
    // utime and stime, fields 14 and 15 of /proc/self/stat, in clock ticks (100 per second).
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|s| s.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let mut args = std::env::args().skip(1);
    let file = args.next().expect("usage: gen_time FILE [ROUNDS]");
    let rounds: usize = args.next().and_then(|r| r.parse().ok()).unwrap_or(3);
    let bytes = std::fs::read(&file).expect("read the file");
    let (mut read, mut expand, mut render) = (f64::MAX, f64::MAX, f64::MAX);
    let mut size = 0;
    for _ in 0..rounds {
        let t0 = cpu_seconds();
        let parsed = eds::parse(&file, &bytes, &eds::Options::lenient());
        let t1 = cpu_seconds();
        let g = od_codegen::expand_text(&parsed.model, &od_codegen::Options::new("device", file.clone()));
        let t2 = cpu_seconds();
        let text = g.render(&file).expect("render");
        let t3 = cpu_seconds();
        size = text.len();
        std::hint::black_box(text);
        read = read.min(t1 - t0);
        expand = expand.min(t2 - t1);
        render = render.min(t3 - t2);
    }
    println!(
        "read {read:.2} s, expand {expand:.2} s, render {render:.2} s; total {:.2} s (CPU, best of {rounds}); {size} bytes",
        read + expand + render
    );
}
