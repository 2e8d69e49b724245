//! Per-stage costs of the glove side: render one bin, encode one packet, decode a stream.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use tactus_glove::{BinFeatures, Decoder, Frame, GloveMap, Packet};

fn benches(c: &mut Criterion) {
    let map = GloveMap::default();
    let f = BinFeatures {
        level: [0, 3, 8, 5],
        note_onset: [false, true, false, true],
        band_beat: [true, false, true, false],
    };
    c.bench_function("render_bin_default_map", |b| {
        b.iter(|| map.render(black_box(&f), 8))
    });

    let p = Packet::pins(7, 1234, Frame([0x5a; 10]));
    c.bench_function("encode_packet", |b| b.iter(|| black_box(&p).encode()));

    // 1000 packets (16 kB), the stream of 100 s at 100 ms bins.
    let stream: Vec<u8> = (0..1000u32)
        .flat_map(|i| Packet::pins(i as u8, (i * 100) as u16, Frame([i as u8; 10])).encode())
        .collect();
    let mut g = c.benchmark_group("decode");
    g.throughput(Throughput::Bytes(stream.len() as u64));
    g.bench_function("1000_packets", |b| {
        b.iter(|| {
            let mut d = Decoder::new();
            let mut n = 0u32;
            d.push(black_box(&stream), &mut |_| n += 1);
            n
        })
    });
    g.finish();
}

criterion_group!(glove, benches);
criterion_main!(glove);
