//! The committed example search result (`designs/optimized/`): its design files load,
//! validate and round-trip like every bundled design.

use std::path::Path;

use tdpcr::Tdpcr;

#[test]
fn the_committed_optimized_designs_load_validate_and_round_trip() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../designs/optimized");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "ron") {
            continue;
        }
        let design = Tdpcr::from_ron_file(&path).unwrap();
        let again = Tdpcr::from_ron_str(&design.to_ron_string(), "round trip").unwrap();
        assert_eq!(design, again, "{}", path.display());
        seen += 1;
    }
    assert!(seen >= 1, "no design file in {}", dir.display());
}
