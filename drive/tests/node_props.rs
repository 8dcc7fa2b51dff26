//! Properties of the node runner and the storage format: no frame sequence makes a node of any
//! kind panic or stop answering, and no bytes make the image decoder panic or accept a
//! damaged image.

use drive::node::{AnyNode, DefaultApps, DeviceKind, NodeConfig};
use drive::storage::{Record, decode_image, encode_image};
use od_bus::CanFrame;
use od_runtime::od::Area;
use proptest::prelude::*;

fn any_frame() -> impl Strategy<Value = CanFrame> {
    prop_oneof![
        // Mostly frames for node 5's services, so they reach deep into the runtime.
        4 => (prop::sample::select(vec![0x000u32, 0x080, 0x205, 0x305, 0x605, 0x705, 0x701]), prop::collection::vec(any::<u8>(), 0..=8))
            .prop_map(|(id, d)| CanFrame::standard(id, &d).unwrap()),
        2 => (0u32..=0x7FF, prop::collection::vec(any::<u8>(), 0..=8)).prop_map(|(id, d)| CanFrame::standard(id, &d).unwrap()),
        1 => (0u32..=0x7FF, 0u8..=8).prop_map(|(id, dlc)| CanFrame::remote(id, false, dlc).unwrap()),
        1 => (0u32..=0x1FFF_FFFF, prop::collection::vec(any::<u8>(), 0..=8)).prop_map(|(id, d)| CanFrame::extended(id, &d).unwrap()),
    ]
}

fn node(kind: DeviceKind) -> Box<dyn AnyNode> {
    kind.build(&NodeConfig { node_id: Some(5), ..NodeConfig::default() }, &DefaultApps).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn hostile_frames_never_stop_a_node(
        kind in prop::sample::select(DeviceKind::ALL.to_vec()),
        frames in prop::collection::vec((any_frame(), 0u64..5_000), 0..200),
    ) {
        let mut node = node(kind);
        let mut now = 0;
        let mut sent = 0usize;
        for (frame, dt) in &frames {
            now += dt;
            node.handle(frame, now);
            node.poll(now, &mut |_| sent += 1);
        }
        // Whatever happened, a reset communication brings it back, and it answers an SDO.
        now += 2_000_000;
        node.handle(&"000#8205".parse().unwrap(), now);
        let mut out = Vec::new();
        node.poll(now, &mut |f| out.push(f.to_string()));
        prop_assert!(out.contains(&"705#00".to_string()), "{:?}", out);
        node.handle(&"605#4000100000000000".parse().unwrap(), now + 10);
        out.clear();
        node.poll(now + 10, &mut |f| out.push(f.to_string()));
        prop_assert!(out.iter().any(|f| f.starts_with("585#43001000")), "{:?}", out);
    }

    #[test]
    fn the_image_decoder_survives_any_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let _ = decode_image(&bytes, Area::Communication, "x");
    }

    #[test]
    fn images_round_trip_and_any_damage_is_refused(
        records in prop::collection::vec((any::<u16>(), any::<u8>(), prop::collection::vec(any::<u8>(), 0..40)), 0..20),
        flip in any::<prop::sample::Index>(),
        bit in 0u8..8,
    ) {
        let records: Vec<Record> = records.into_iter().map(|(index, sub, data)| Record { index, sub, data }).collect();
        let bytes = encode_image(Area::Manufacturer, "dev-node5", &records);
        prop_assert_eq!(decode_image(&bytes, Area::Manufacturer, "dev-node5"), Ok(records));
        let mut damaged = bytes.clone();
        let i = flip.index(damaged.len());
        damaged[i] ^= 1 << bit;
        prop_assert!(decode_image(&damaged, Area::Manufacturer, "dev-node5").is_err());
        let cut = flip.index(bytes.len());
        prop_assert!(decode_image(&bytes[..cut], Area::Manufacturer, "dev-node5").is_err());
    }
}
