// Every PDO mistake of `od_macros::tests::pdo_errors`, each on the tokens that caused it.
od_macros::object_dictionary! {
    var 0x2000 "A": u32, rww, pdo;
    var 0x2001 "B": u32, rww, pdo;
    var 0x2002 "C": u32, rww, pdo;
    var 0x2003 "Status": u16, ro, pdo;
    var 0x2004 "Hidden": u16, rw;
    var 0x2005 "Name": VISIBLE_STRING, rw, pdo, default = "x";
    rpdo 1: map = [0x2000, 0x2001, 0x2002];
    rpdo 2: map = [0x2003];
    tpdo 1: map = [0x2004];
    tpdo 2: map = [0x2005, 0x2099, 0x2000:4];
    tpdo 3: capacity = 1, map = [0x2000, 0x2001];
    rpdo 4: inhibit = 5, cob_id = NODEID + 0x1_0000_0000;
    rpdo 600;
    tpdo 1: map = [];
}

fn main() {}
