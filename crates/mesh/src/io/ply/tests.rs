use super::*;

#[test]
fn scalars_decode_in_both_byte_orders() {
    let cases: [(&str, Vec<u8>, f64); 8] = [
        ("int8", vec![0xfe], -2.0),
        ("uchar", vec![0xfe], 254.0),
        ("short", vec![0xff, 0x38], -200.0),
        ("uint16", vec![0x01, 0x02], 258.0),
        ("int", (-70000i32).to_be_bytes().to_vec(), -70000.0),
        ("uint", 4_000_000_000u32.to_be_bytes().to_vec(), 4e9),
        ("float", 0.1f32.to_be_bytes().to_vec(), f64::from(0.1f32)),
        ("float64", 0.1f64.to_be_bytes().to_vec(), 0.1),
    ];
    for (name, big_endian, value) in cases {
        let ty = Scalar::from_name(name).unwrap();
        assert_eq!(ty.size(), big_endian.len());
        assert_eq!(ty.decode(&big_endian, true), Some(value), "{name}");
        let little_endian: Vec<u8> = big_endian.iter().rev().copied().collect();
        assert_eq!(ty.decode(&little_endian, false), Some(value), "{name}");
        assert_eq!(ty.decode(&big_endian[1..], true), None, "{name} too short");
    }
    assert_eq!(Scalar::from_name("float16"), None);
}

#[test]
fn whole_accepts_only_non_negative_whole_numbers() {
    assert_eq!(whole(0.0), Some(0));
    assert_eq!(whole(4e9), Some(4_000_000_000));
    for bad in [-1.0, 0.5, f64::NAN, f64::INFINITY, -0.25] {
        assert_eq!(whole(bad), None, "{bad}");
    }
}
