// Default PDO mappings are checked against what they map.
od_macros::object_dictionary! {
    var 0x2000 "Target position": i32, rww, pdo;
    var 0x2001 "Target velocity": i32, rww, pdo;
    var 0x2002 "Target torque": i32, rww, pdo;
    var 0x2003 "Actual position": i32, ro, pdo;
    var 0x2004 "Internal": u16, rw;

    rpdo 1: map = [0x2000, 0x2001, 0x2002];      // 96 bits: over 64
    rpdo 2: map = [0x2003];                      // read-only entry in an RPDO
    tpdo 1: map = [0x2004, 0x2005];              // not PDO-mappable; not declared
}

fn main() {}
