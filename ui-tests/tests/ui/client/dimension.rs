// A quantity of the wrong dimension does not compile: a velocity where a position goes, a
// position to the axis's homing, a number where a quantity goes.
use od_master::remote::Quantity;

od_macros::include_eds!("../../../tmp/client-ui/camozzi-drvi.eds", mod drvi, client);

async fn use_it(drvi: &drvi::remote::Remote, units: &drvi::units::Units) {
    drvi.target_position().write_in(units, Quantity::mm(12.5)).await.unwrap();
    drvi.target_position().write_in(units, Quantity::rpm(60)).await.unwrap();
    drvi.profile_velocity().write_in(units, Quantity::deg(90)).await.unwrap();
    drvi.target_position().write_in(units, 1250).await.unwrap();
}

fn main() {
    let _ = use_it;
}
