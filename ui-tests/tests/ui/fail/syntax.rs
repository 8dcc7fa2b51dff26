// `od_macros::tests::syntax_errors_recover_at_the_next_item`: after a syntax error the macro
// goes on at the next item, so every mistake is reported in one compile, on its tokens.
od_macros::object_dictionary! {
    mod a;
    mod b;
    strict;
    strict;
    device { vendor_name = 5, colour = "red", vendor_name = "x", baud_rates = [300] }
    device { }
    var "no index";
    var 0x2000: u8, rw;
    var 0x2001 "A" u8, rw;
    var 0x2002 "B": , rw;
    record 0x2003 "R": u8, rw { 1 "a": u8, rw; }
    record 0x2004 "S" { 1 "a" u8; 2 "b": u8, rw }
    array 0x2005 "T": u8, rw { 1 "a": u8; }
    var 0x2006 "C": u8, rw, default = 1u8;
    var 0x2007 "D": u8, rw, default = 1 2;
    var 0x2008 "E": u8, rw
    var 0x2009 "F": u8, rw;
}

fn main() {}
