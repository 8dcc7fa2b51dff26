//! The build.rs path and `cargo xtask gen` use one emitter: same description, same bytes.

#[test]
fn build_rs_output_equals_the_checked_in_module() {
    let from_build_rs = include_str!(concat!(env!("OUT_DIR"), "/drvi.rs"));
    let checked_in = include_str!("../../../generated/src/drvi.rs");
    assert!(from_build_rs == checked_in, "OUT_DIR/drvi.rs differs from generated/src/drvi.rs; run `cargo xtask gen`");
}

#[test]
fn the_generated_module_is_usable() {
    let mut od = build_rs_user::drvi::Dictionary::new(32);
    assert_eq!(build_rs_user::on_rpdo1(&mut od, &[0x06, 0x00]), Some(0));
    assert_eq!(od.controlword(), 6);
    assert_eq!(build_rs_user::on_rpdo1(&mut od, &[0x06]), None);
}
