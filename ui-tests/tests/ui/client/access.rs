// Access is in the types: no `write` on a `ro` object (6041h statusword), no `read` on a `wo`
// one (AKD 1026h sub 1, OS prompt StdIn).
od_macros::include_eds!("../../../tmp/client-ui/camozzi-drvi.eds", mod drvi, client);
od_macros::include_eds!("../../../tmp/client-ui/kollmorgen-akd.eds", mod akd, client);

async fn use_it(drvi: &drvi::remote::Remote, akd: &akd::remote::Remote) {
    drvi.statusword().read().await.unwrap();
    drvi.statusword().write(0x0006).await.unwrap();
    akd.os_prompt_std_in().write(b'a').await.unwrap();
    akd.os_prompt_std_in().read().await.unwrap();
}

fn main() {
    let _ = use_it;
}
