//! The built-in curves' planned tables cut into streaming chunks: the
//! chunks decode to the table's own q spans and pieces, word for word, at
//! several chunk lengths, with and without the u form; the stream's bytes
//! per mm are printed (`cargo test -p planner-host --test suite stream:: -- --nocapture`).

use firmware_core::stream::{Chunk, ChunkRing};
use firmware_core::Table;
use planner_host::plan::{plan_curve, PlanConfig};
use planner_host::stream::{
    chunk_table, decode_chunks, first_difference, ChunkOptions, ChunkTableError, StreamSize, TableRows,
};
use planner_host::{builtin, ArcLength};

#[test]
fn builtin_curves_stream_losslessly_and_print_bytes_per_mm() {
    for name in builtin::NAMES {
        let curve = builtin::by_name(name).unwrap().unwrap();
        let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
        let table = Table::parse(&out.table_bytes).unwrap();
        let rows = TableRows::of(&table);
        let length = ArcLength::new(&curve).total();
        for chunk_mm in [4.0, 32.0] {
            for u_form in [true, false] {
                let opts = ChunkOptions {
                    chunk_mm,
                    u_form,
                    ..ChunkOptions::default()
                };
                let chunks = chunk_table(&table, &opts).unwrap();
                let decoded = decode_chunks(&chunks).unwrap();
                assert_eq!(
                    first_difference(&rows, &decoded, u_form),
                    None,
                    "{name} {chunk_mm} mm u form {u_form}"
                );
                // the whole stream through a ring, in order
                let mut ring: ChunkRing<{ 1 << 20 }, 1024> = ChunkRing::new();
                for c in &chunks {
                    ring.push(c).unwrap();
                }
                assert!(ring.has_last());
                let size = StreamSize::of(&chunks);
                println!(
                    "{name:9} L {length:7.2} mm, {chunk_mm:2} mm chunks, u form {u_form:5}: {:4} chunks, {:8.1} B/mm chunks, {:8.1} B/mm framed",
                    size.chunks,
                    size.chunk_bytes as f64 / length,
                    size.framed_bytes as f64 / length,
                );
            }
        }
        // and the table itself, for comparison
        println!(
            "{name:9} table {:8.1} B/mm",
            out.table_bytes.len() as f64 / length
        );
    }
}

#[test]
fn every_chunk_covers_its_stretch_and_chunks_tile_the_path() {
    let curve = builtin::by_name("trident").unwrap().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let chunks = chunk_table(&table, &ChunkOptions::default()).unwrap();
    let infos: Vec<_> = chunks.iter().map(|c| *Chunk::parse(c).unwrap().info()).collect();
    assert_eq!(infos[0].s_a, 0);
    for w in infos.windows(2) {
        assert_eq!(w[0].s_b, w[1].s_a);
    }
    for c in &chunks {
        let c = Chunk::parse(c).unwrap();
        let i = c.info();
        // the q spans reach over [s_a, s_b]
        let spans: Vec<_> = c.q_spans().collect();
        assert!(spans.first().unwrap().start_fx() <= i.s_a);
        assert!(firmware_core::stream::QSpanForm::start_fx(spans.last().unwrap()) < i.s_b);
        let last_end = spans.iter().map(|q| q.end).fold(f64::MIN, f64::max);
        assert!(last_end * (1u64 << 40) as f64 >= i.s_b as f64);
    }
    assert_eq!(
        chunk_table(
            &table,
            &ChunkOptions {
                chunk_mm: 0.0,
                ..ChunkOptions::default()
            }
        )
        .unwrap_err(),
        ChunkTableError::ChunkLength(0.0)
    );
}

#[test]
fn a_byte_bound_halves_long_chunks_and_stays_lossless() {
    let curve = builtin::by_name("butterfly").unwrap().unwrap();
    let out = plan_curve(&curve, &PlanConfig::default()).unwrap();
    let table = Table::parse(&out.table_bytes).unwrap();
    let rows = TableRows::of(&table);
    let free = chunk_table(&table, &ChunkOptions::default()).unwrap();
    let max = 2048;
    assert!(
        free.iter().any(|c| c.len() > max),
        "the unbounded cut has chunks over {max} bytes"
    );
    let opts = ChunkOptions {
        max_chunk_bytes: Some(max),
        ..ChunkOptions::default()
    };
    let chunks = chunk_table(&table, &opts).unwrap();
    assert!(chunks.len() > free.len());
    for c in &chunks {
        let info = *Chunk::parse(c).unwrap().info();
        assert!(
            c.len() <= max || info.n_p == 1,
            "{} bytes, {} pieces",
            c.len(),
            info.n_p
        );
    }
    assert_eq!(
        first_difference(&rows, &decode_chunks(&chunks).unwrap(), opts.u_form),
        None
    );
    let mut ring: ChunkRing<{ 1 << 20 }, 1024> = ChunkRing::new();
    for c in &chunks {
        ring.push(c).unwrap();
    }
    assert!(ring.has_last());
}
