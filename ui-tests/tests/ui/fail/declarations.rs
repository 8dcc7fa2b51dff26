// One dictionary, many mistakes: all of them are reported in one compile, each on its token.
od_macros::object_dictionary! {
    var 0x2000 "Speed": u16, rw, default = 0;
    var 0x2000 "Speed again": u16, rw;           // duplicate index
    record 0x2001 "Gains" {
        1 "Kp": u16, rw;
        256 "Kd": u16, rw;                        // sub-index out of range
    }
    var 0x2002 "Torque": u33, rw;                // unknown data type
    var 0x2003 "Mode": i8, rx;                   // unknown access keyword
    var 0x2004 "Level": u8, rw, default = 300;   // default out of range
    var 0x2005 "Ratio": i16, rw, default = 50, min = 0, max = 40;
}

fn main() {}
