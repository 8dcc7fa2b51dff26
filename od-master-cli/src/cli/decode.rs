//! `monitor`: each frame said in words, through the devices' descriptions where given.

use std::collections::BTreeMap;

use serde_json::{Value as Json, json};

use super::device::Device;
use super::value::{hex, show};

/// A frame in words.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// `nmt`, `sync`, `time`, `emcy`, `pdo`, `sdo-request`, `sdo-response`, `heartbeat`, `lss`,
    /// `other`.
    pub kind: &'static str,
    /// The node the frame is from or for.
    pub node: Option<u8>,
    /// One line of text.
    pub text: String,
    /// The same as JSON fields (with `kind`, `id`, `data`, `node`).
    pub json: Json,
}

/// The NMT state of a heartbeat's byte.
pub fn nmt_state(byte: u8) -> &'static str {
    match byte & 0x7F {
        0x00 => "boot-up",
        0x04 => "stopped",
        0x05 => "operational",
        0x7F => "pre-operational",
        _ => "unknown state",
    }
}

/// The CiA 301 class of an emergency error code (its high byte, or the whole code for the
/// reset and generic ones).
pub fn emcy_class(code: u16) -> &'static str {
    match code {
        0x0000 => "error reset or no error",
        0x1000..=0x10FF => "generic error",
        0x2000..=0x20FF => "current",
        0x2100..=0x21FF => "current, device input side",
        0x2200..=0x22FF => "current inside the device",
        0x2300..=0x23FF => "current, device output side",
        0x3000..=0x30FF => "voltage",
        0x3100..=0x31FF => "mains voltage",
        0x3200..=0x32FF => "voltage inside the device",
        0x3300..=0x33FF => "output voltage",
        0x4000..=0x40FF => "temperature",
        0x4100..=0x41FF => "ambient temperature",
        0x4200..=0x42FF => "device temperature",
        0x5000..=0x50FF => "device hardware",
        0x6000..=0x60FF => "device software",
        0x6100..=0x61FF => "internal software",
        0x6200..=0x62FF => "user software",
        0x6300..=0x63FF => "data set",
        0x7000..=0x70FF => "additional modules",
        0x8000..=0x80FF => "monitoring",
        0x8100..=0x810F => "communication",
        0x8110 => "CAN overrun (objects lost)",
        0x8120 => "CAN in error passive mode",
        0x8130 => "life guard or heartbeat error",
        0x8140 => "recovered from bus off",
        0x8150 => "CAN-ID collision",
        0x8111..=0x81FF => "communication",
        0x8200..=0x820F => "protocol error",
        0x8210 => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8230 => "DAM MPDO not processed, destination object not available",
        0x8240 => "unexpected SYNC data length",
        0x8250 => "RPDO timeout",
        0x8211..=0x82FF => "protocol error",
        0x8300..=0x8FFF => "monitoring",
        0x9000..=0x90FF => "external error",
        0xF000..=0xF0FF => "additional functions",
        0xFF00..=0xFFFF => "device specific",
        _ => "unknown class",
    }
}

fn nmt_command(cs: u8) -> &'static str {
    match cs {
        0x01 => "start",
        0x02 => "stop",
        0x80 => "enter pre-operational",
        0x81 => "reset node",
        0x82 => "reset communication",
        _ => "unknown command",
    }
}

/// Decodes the frame `id`/`data` (an RTR frame: `rtr`), with `devices` by node id.
pub fn decode(id: u32, rtr: bool, data: &[u8], devices: &BTreeMap<u8, Device>) -> Decoded {
    let base = json!({ "id": id, "data": hex(data) });
    let mk = |kind: &'static str, node: Option<u8>, text: String, extra: Json| {
        let mut j = base.clone();
        if let (Json::Object(m), Json::Object(e)) = (&mut j, extra) {
            m.insert("kind".into(), kind.into());
            m.insert("node".into(), node.map_or(Json::Null, Into::into));
            m.extend(e);
        }
        Decoded { kind, node, text, json: j }
    };
    // PDOs first: a device may map one anywhere.
    for (node, dev) in devices {
        if let Some(pdo) = dev.pdos(*node).iter().find(|p| p.cob_id == id) {
            return pdo_fields(*node, dev, pdo, data, &mk);
        }
    }
    let node = (id & 0x7F) as u8;
    let f = id & 0x780;
    match (id, f) {
        (0x000, _) if data.len() == 2 => {
            let target = if data[1] == 0 { "all".to_owned() } else { format!("node {}", data[1]) };
            let what = nmt_command(data[0]);
            mk("nmt", (data[1] != 0).then_some(data[1]), format!("NMT {what} {target}"), json!({ "command": what }))
        }
        (0x080, _) => match data.first() {
            Some(c) => mk("sync", None, format!("SYNC counter {c}"), json!({ "counter": c })),
            None => mk("sync", None, "SYNC".into(), json!({})),
        },
        (0x100, _) => mk("time", None, format!("TIME {}", hex(data)), json!({})),
        (_, 0x080) if data.len() == 8 => {
            let code = u16::from_le_bytes([data[0], data[1]]);
            let class = emcy_class(code);
            let text = devices.get(&node).and_then(|d| d.emcy_text(code, &data[3..]));
            let line = format!(
                "EMCY node {node}: {code:04X}h {class}{}, register {:02X}h, vendor {}",
                text.map(|t| format!(": {t}")).unwrap_or_default(),
                data[2],
                hex(&data[3..])
            );
            mk(
                "emcy",
                Some(node),
                line,
                json!({ "code": code, "class": class, "text": text, "register": data[2], "vendor": hex(&data[3..]) }),
            )
        }
        (_, 0x580) | (_, 0x600) => sdo(node, f == 0x600, data, devices, &mk),
        (_, 0x700) if rtr => mk("guard", Some(node), format!("node guarding request to node {node}"), json!({})),
        (_, 0x700) if data.len() == 1 => {
            let state = nmt_state(data[0]);
            mk("heartbeat", Some(node), format!("heartbeat node {node}: {state}"), json!({ "state": state }))
        }
        (0x7E4 | 0x7E5, _) => mk("lss", None, format!("LSS {}", hex(data)), json!({})),
        _ => mk("other", None, format!("{id:03X}h [{}] {}", data.len(), hex(data)), json!({})),
    }
}

fn pdo_fields(
    node: u8,
    dev: &Device,
    pdo: &super::device::Pdo,
    data: &[u8],
    mk: &dyn Fn(&'static str, Option<u8>, String, Json) -> Decoded,
) -> Decoded {
    let mut bit = 0usize;
    let mut parts = Vec::new();
    let mut fields = serde_json::Map::new();
    for f in &pdo.fields {
        let bits = usize::from(f.bits);
        if bits == 0 || bit + bits > data.len() * 8 {
            break;
        }
        // Only whole bytes are shown by type; bit fields as unsigned numbers.
        let mut v: u128 = 0;
        for i in 0..bits {
            let b = bit + i;
            v |= u128::from(data[b / 8] >> (b % 8) & 1) << i;
        }
        bit += bits;
        if f.index < 0x1000 {
            continue; // a dummy entry fills a gap
        }
        let name =
            dev.names.name_of(f.index, f.sub).map_or_else(|| format!("{:04X}h:{}", f.index, f.sub), str::to_owned);
        let dt = dev.model.entry(f.index, f.sub).map(|e| e.data_type);
        let shown = if bits % 8 == 0 {
            let bytes = &v.to_le_bytes()[..bits / 8];
            show(bytes, dt, f.index, f.sub)
        } else {
            super::value::Shown::Int(v as i128)
        };
        parts.push(format!("{name}={}", shown.text()));
        fields.insert(name, shown.json());
    }
    mk(
        "pdo",
        Some(node),
        format!("{} node {node}: {}", pdo.name, parts.join(" ")),
        json!({ "pdo": pdo.name, "fields": fields }),
    )
}

fn sdo(
    node: u8,
    request: bool,
    data: &[u8],
    _devices: &BTreeMap<u8, Device>,
    mk: &dyn Fn(&'static str, Option<u8>, String, Json) -> Decoded,
) -> Decoded {
    let kind = if request { "sdo-request" } else { "sdo-response" };
    let Some(&b0) = data.first() else { return mk(kind, Some(node), format!("SDO node {node}: empty"), json!({})) };
    let obj = (data.len() >= 4).then(|| (u16::from_le_bytes([data[1], data[2]]), data[3]));
    let at = obj.map(|(i, s)| format!(" {i:04X}h:{s}")).unwrap_or_default();
    let cs = b0 >> 5;
    let what = match (request, cs) {
        (_, 4) => {
            let code = data.get(4..8).map_or(0, |c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
            format!("abort{at}: {code:08X}h {}", abort_name(code))
        }
        (true, 1) if b0 & 0x02 != 0 => format!("download{at} expedited {}", hex(expedited(b0, data))),
        (true, 1) => format!("download{at} segmented"),
        (true, 2) => format!("upload{at}"),
        (true, 0) => format!("download segment ({} bytes)", 7 - usize::from(b0 >> 1 & 7)),
        (true, 3) => "upload segment request".to_owned(),
        (true, 6) => format!("block download{at}"),
        (true, 5) => format!("block upload{at}"),
        (false, 2) if b0 & 0x02 != 0 && b0 & 0x01 != 0 => {
            format!("upload{at} = {}", hex(expedited(b0, data)))
        }
        (false, 2) => format!("upload{at} segmented"),
        (false, 3) => format!("download{at} ok"),
        (false, 0) => format!("upload segment ({} bytes)", 7 - usize::from(b0 >> 1 & 7)),
        (false, 1) => "download segment ok".to_owned(),
        (false, 5) => format!("block download{at} answer"),
        (false, 6) => format!("block upload{at} answer"),
        _ => hex(data),
    };
    let mut extra = json!({ "summary": what });
    if let (Some((i, s)), Json::Object(m)) = (obj.filter(|_| matches!(cs, 1 | 2 | 4 | 5 | 6)), &mut extra) {
        m.insert("index".into(), i.into());
        m.insert("subindex".into(), s.into());
    }
    let dir = if request { "->" } else { "<-" };
    mk(kind, Some(node), format!("SDO {dir} node {node}: {what}"), extra)
}

/// The data of an expedited transfer: bytes 4.. less the unused ones its command byte counts
/// (all four when it gives no size).
fn expedited(b0: u8, data: &[u8]) -> &[u8] {
    let unused = if b0 & 0x01 != 0 { usize::from(b0 >> 2 & 3) } else { 0 };
    data.get(4..).map_or(&[][..], |d| &d[..d.len().saturating_sub(unused).min(4)])
}

/// The CiA 301 name of an SDO abort code.
pub fn abort_name(code: u32) -> &'static str {
    match code {
        0x0503_0000 => "toggle bit not alternated",
        0x0504_0000 => "SDO protocol timed out",
        0x0504_0001 => "command specifier not valid or unknown",
        0x0504_0002 => "invalid block size",
        0x0504_0003 => "invalid sequence number",
        0x0504_0004 => "CRC error",
        0x0504_0005 => "out of memory",
        0x0601_0000 => "unsupported access to an object",
        0x0601_0001 => "attempt to read a write only object",
        0x0601_0002 => "attempt to write a read only object",
        0x0602_0000 => "object does not exist in the object dictionary",
        0x0604_0041 => "object cannot be mapped to the PDO",
        0x0604_0042 => "the number and length of the objects to be mapped would exceed PDO length",
        0x0604_0043 => "general parameter incompatibility",
        0x0604_0047 => "general internal incompatibility in the device",
        0x0606_0000 => "access failed due to a hardware error",
        0x0607_0010 => "data type does not match, length of service parameter does not match",
        0x0607_0012 => "data type does not match, length of service parameter too high",
        0x0607_0013 => "data type does not match, length of service parameter too low",
        0x0609_0011 => "sub-index does not exist",
        0x0609_0030 => "invalid value for parameter",
        0x0609_0031 => "value of parameter written too high",
        0x0609_0032 => "value of parameter written too low",
        0x0609_0036 => "maximum value is less than minimum value",
        0x060A_0023 => "resource not available: SDO connection",
        0x0800_0000 => "general error",
        0x0800_0020 => "data cannot be transferred or stored to the application",
        0x0800_0021 => "data cannot be transferred or stored because of local control",
        0x0800_0022 => "data cannot be transferred or stored because of the present device state",
        0x0800_0023 => "object dictionary dynamic generation fails or no object dictionary is present",
        0x0800_0024 => "no data available",
        _ => "unknown abort code",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(id: u32, data: &[u8]) -> Decoded {
        decode(id, false, data, &BTreeMap::new())
    }

    #[test]
    fn frames_of_each_service() {
        assert_eq!(d(0x000, &[0x01, 0x05]).text, "NMT start node 5");
        assert_eq!(d(0x000, &[0x81, 0x00]).text, "NMT reset node all");
        assert_eq!(d(0x080, &[7]).text, "SYNC counter 7");
        assert_eq!(d(0x705, &[0x05]).text, "heartbeat node 5: operational");
        assert_eq!(d(0x705, &[0x00]).json["state"], "boot-up");
        let e = d(0x085, &[0x00, 0x81, 0x11, 0, 0, 0, 0, 0]);
        assert_eq!(e.kind, "emcy");
        assert_eq!(e.json["class"], "communication");
        assert_eq!(d(0x085, &[0x30, 0x81, 0x11, 0, 0, 0, 0, 0]).json["class"], "life guard or heartbeat error");
        assert_eq!(d(0x605, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).text, "SDO -> node 5: upload 6041h:0");
        assert_eq!(d(0x585, &[0x4B, 0x41, 0x60, 0, 0x37, 0x02, 0, 0]).text, "SDO <- node 5: upload 6041h:0 = 3702");
        let abort = d(0x585, &[0x80, 0x00, 0x20, 0, 0, 0, 0x02, 0x06]);
        assert_eq!(
            abort.text,
            "SDO <- node 5: abort 2000h:0: 06020000h object does not exist in the object dictionary"
        );
        assert_eq!(abort.json["index"], 0x2000);
    }

    fn drvi_on(node: u8) -> BTreeMap<u8, Device> {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/camozzi-drvi.eds");
        BTreeMap::from([(node, Device::load(std::path::Path::new(path)).unwrap())])
    }

    #[test]
    fn through_a_device_pdos_have_named_fields_and_emcy_the_sidecar_text() {
        let devices = drvi_on(5);
        // TPDO1 of the DRVI maps the statusword (its EDS default), on 180h + node.
        let pdo = decode(0x185, false, &[0x37, 0x02], &devices);
        assert_eq!(pdo.kind, "pdo");
        assert_eq!(pdo.text, "TPDO1 node 5: statusword=567");
        assert_eq!(pdo.json["fields"]["statusword"], 0x237);
        let emcy = decode(0x085, false, &[0x10, 0x23, 0x03, 0, 0, 0, 0, 0], &devices);
        assert_eq!(emcy.json["text"], "Over current error");
        assert_eq!(emcy.json["class"], "current, device output side");
        // Another node's frames are not read through this device.
        assert_eq!(decode(0x086, false, &[0x10, 0x23, 0x03, 0, 0, 0, 0, 0], &devices).json["text"], Json::Null);
    }

    #[test]
    fn every_frame_decodes_without_panicking() {
        let devices = drvi_on(5);
        for id in (0..0x800u32).step_by(3) {
            for len in 0..=8usize {
                let data: Vec<u8> = (0..len as u8).map(|b| b.wrapping_mul(37).wrapping_add(id as u8)).collect();
                let _ = decode(id, len == 0, &data, &BTreeMap::new());
                let _ = decode(id, len == 0, &data, &devices);
            }
        }
    }
}
