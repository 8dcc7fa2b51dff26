//! The module's EDS (`io::EDS`, written by the macro from the inline declaration) is checked in
//! as `tests/io-module.eds`, and `include_eds!` reads it back, strictly, into the same dictionary.

use inline_macro_user::io;

od_macros::include_eds!("tests/io-module.eds", mod from_file, strict);

#[test]
fn checked_in_eds_is_current() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/io-module.eds");
    let on_disk = std::fs::read_to_string(path).unwrap();
    assert!(
        on_disk == io::EDS,
        "tests/io-module.eds is stale: run `cargo run -p inline-macro-user -- --eds > examples/inline-macro-user/tests/io-module.eds`"
    );
}

#[test]
fn include_eds_of_the_inline_eds_gives_the_same_dictionary() {
    assert_eq!(from_file::ENTRIES, io::ENTRIES);
    assert_eq!(from_file::EDS, io::EDS);
    let a = io::Dictionary::new(9);
    let b = from_file::Dictionary::new(9);
    assert_eq!(a.identity_object_serial_number(), b.identity_object_serial_number());
    assert_eq!(a.temperature(), b.temperature());
    assert_eq!(io::pdo::Tpdo1::from_dictionary(&a).pack(), from_file::pdo::Tpdo1::from_dictionary(&b).pack());
}
