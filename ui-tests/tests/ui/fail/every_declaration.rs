// Every declaration mistake of `od_macros::tests::every_declaration_error_in_one_pass_on_its_token`:
// all reported in one compile, each on the tokens that caused it.
od_macros::object_dictionary! {
    var 0x2000 "A": u8, rw, default = 300;
    var 0x2000 "B": u33, rx;
    record 0x2001 "R" { 256 "x": u8, ro; 1 "y": u8, ro; 1 "z": u8, ro; }
    var 0x2002 "C": u8, rw, pdo = 1, bogus = 3, default = -1;
    var 0x2003 "D": u8 rw;
    frob 0x2004;
    var 0x0005 "E": u8, rw;
    var 0x10000 "F": u8, rw;
    var 0x2006 "G": i16, rw, default = 5, min = 10, max = 0;
    var 0x2007 "H": u16, rw, default = 70, max = 60;
    array 0x2008 "I": u8, ro, len = 2 { 1 "x"; }
    array 0x2009 "J": u8, ro { 0 "zero"; 1 "one": u8, ro; 1 "dup"; }
    var 0x200A "K": VISIBLE_STRING, ro, default = 5, min = 1;
    var 0x200B "L": u32, rw, min = NODEID + 1;
    var 0x200C " M": u8, rw;
    var 0x200D "N": u64, rw, default = NODEID + 170141183460469231731687303715884105727;
    var 0x200E "O": u64, rw, default = 340282366920938463463374607431768211456;
    var 0x200F "P": u64, rw, default = -170141183460469231731687303715884105727;
}

fn main() {}
