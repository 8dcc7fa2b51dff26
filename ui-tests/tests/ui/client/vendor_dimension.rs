// A vendor's file without a sidecar (the DRVI's description alone, as a vendor ships it): CiA
// 402's positions and velocities are still typed by dimension, in the vendor's names and in
// the standard's (`od_master::profile::Cia402`).
use od_master::profile::Cia402;
use od_master::remote::Quantity;

od_macros::include_eds!("../../../tmp/client-ui/vendor-drvi.eds", mod drvi, client, allow(warnings));

async fn use_it(drvi: &drvi::remote::Remote, units: &drvi::units::Units) {
    drvi.target_position().write_in(units, Quantity::user(100)).await.unwrap();
    drvi.target_position().write_in(units, Quantity::user_per_s(60)).await.unwrap();
    Cia402::target_velocity(drvi).unwrap().write_in(units, Quantity::user(90)).await.unwrap();
}

fn main() {
    let _ = use_it;
}
