// `strict;` validates like `odgen check --strict`: this fragment (fine in lenient mode) lacks
// the objects CiA 301 makes mandatory.
od_macros::object_dictionary! {
    strict;

    device {
        vendor_name = "Example Automation",
        product_name = "Fragment",
        baud_rates = [250],
    }

    var 0x1001 "Error register": u8, ro, default = 0;
    var 0x2000 "Speed": u16, rw, default = 0;
}

fn main() {}
