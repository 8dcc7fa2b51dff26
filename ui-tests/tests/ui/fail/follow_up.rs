// `od_macros::tests::follow_up_errors_are_not_reported`: an entry of an unknown type is not
// reported again where a PDO maps it, nor is the strict check of mandatory objects.
od_macros::object_dictionary! {
    strict;
    device { vendor_name = "V", product_name = "P", baud_rates = [250] }
    var 0x2000 "A": u33, rw, pdo;
    rpdo 1: map = [0x2000];
    var 0x2001 "B": u8, rw, default = ;
    tpdo 1: map = [0x2001];
}

fn main() {}
