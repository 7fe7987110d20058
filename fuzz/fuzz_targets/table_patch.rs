//! MERL and UTIA parsers on files of the right size: the input is a list of
//! edits (offset, byte) and a length change applied to a valid file, so the
//! header and value checks run (the plain targets mostly stop at the size
//! check, as random bytes are never exactly 35 MB). The first byte picks the
//! format. Slow (a full table per run): run it with -max_len=4096.
#![no_main]
use libfuzzer_sys::fuzz_target;
use npf::loaders::{MerlTable, UtiaTable};
use std::path::Path;
use std::sync::OnceLock;

fn valid(merl: bool) -> &'static [u8] {
    static M: OnceLock<Vec<u8>> = OnceLock::new();
    static U: OnceLock<Vec<u8>> = OnceLock::new();
    if merl {
        M.get_or_init(|| {
            MerlTable::from_fn(|th, td, _| (td < 1.5).then_some([th + 0.1, td, 0.3])).to_bytes()
        })
    } else {
        U.get_or_init(|| {
            UtiaTable::from_fn(|ti, _, tv, _| (ti < 1.2).then_some([ti, tv, 0.3])).to_bytes()
        })
    }
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    // MERL runs cost 17 times UTIA ones: one run in 16.
    let merl = pick & 0x0f == 0;
    let mut b = valid(merl).to_vec();
    // Length change: -8..=7 bytes (0 most of the time).
    let delta = if pick & 0x10 != 0 {
        (pick >> 5) as i64 - 4
    } else {
        0
    };
    for e in rest.chunks_exact(5) {
        let at = u32::from_le_bytes([e[0], e[1], e[2], e[3]]) as usize;
        // Favour the header and the first values.
        let i = if at & 1 == 0 {
            (at >> 1) % 64
        } else {
            (at >> 1) % b.len()
        };
        b[i] = e[4];
    }
    if delta < 0 {
        b.truncate(b.len() - (-delta) as usize);
    } else {
        b.extend(std::iter::repeat(0u8).take(delta as usize));
    }
    let p = Path::new("fuzz");
    if merl {
        if let Ok(t) = MerlTable::from_bytes(&b, p) {
            assert_eq!(t.to_bytes(), b);
        }
    } else if let Ok(t) = UtiaTable::from_bytes(&b, p) {
        assert_eq!(t.to_bytes(), b);
    }
});
