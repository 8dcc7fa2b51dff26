//! `generated/` must be exactly what `cargo xtask gen` writes from the current device files.

#[test]
fn generated_crate_is_up_to_date() {
    let root = xtask::workspace_root();
    let stale = xtask::codegen::stale_files(&root).expect("generation failed");
    assert!(stale.is_empty(), "generated/ is stale; run `{}`. Out of date: {stale:?}", xtask::codegen::FIX);
}
