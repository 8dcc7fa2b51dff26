// The DRVI's description with 607Ah (target position) removed: its client has no
// `target_position` (the test writes the trimmed file from devices/camozzi-drvi.eds).
od_macros::include_eds!("../../../tmp/client-ui/drvi-without-607a.eds", mod drvi, client);

async fn use_it(drvi: &drvi::remote::Remote) {
    drvi.position_actual_value().read().await.unwrap();
    drvi.target_position().write(1000).await.unwrap();
}

fn main() {
    let _ = use_it;
}
