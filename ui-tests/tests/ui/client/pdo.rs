// A PDO field of the wrong type, and a TPDO layout sent as an RPDO, do not compile.
od_macros::include_eds!("../../../tmp/client-ui/camozzi-drvi.eds", mod drvi, client);

async fn use_it(drvi: &drvi::remote::Remote) {
    drvi.rpdo1().send(drvi::pdo::Rpdo1 { controlword: 0x000F }).await.unwrap();
    drvi.rpdo1().send(drvi::pdo::Rpdo1 { controlword: -1i32 }).await.unwrap();
    drvi.rpdo1().send(drvi::pdo::Tpdo1 { statusword: 0 }).await.unwrap();
    let t: drvi::pdo::Tpdo1 = drvi.tpdo1().next().await.unwrap();
    let _: i32 = t.statusword;
}

fn main() {
    let _ = use_it;
}
