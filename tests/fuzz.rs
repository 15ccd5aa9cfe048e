//! Fuzzing the public Rust API (issue #6). The property tests come in a later commit; these
//! are the regression tests of the bugs they found, one per bug, each opening with its story.

mod common;

use rustcloth::scene::{ClothSpec, PinSpec};
use rustcloth::Scene;

// ----- regression tests, one per bug the fuzzer found -----------------------------------------

/// `ClothSpec::pinned_indices` is public and callable on a spec nobody validated, but it
/// computed the last row and column as `nx - 1` and `ny - 1` before anything looked at the
/// grid: a spec with `nx = 0` or `ny = 0` panicked with "attempt to subtract with overflow" (in
/// a debug build; a release build wrapped and named particles of a grid that has none). Found
/// by `scenes_validate_or_fail_cleanly` on its first cases. An empty grid now has no pins.
#[test]
fn issue_pinned_indices_of_an_empty_grid() {
    for (nx, ny) in [(0, 0), (0, 5), (5, 0)] {
        let cloth = ClothSpec {
            nx,
            ny,
            pins: vec![
                PinSpec::Named("top_corners".into()),
                PinSpec::Named("right_edge".into()),
                PinSpec::Cell([0, 0]),
            ],
            ..ClothSpec::default()
        };
        assert_eq!(cloth.pinned_indices(), Vec::<usize>::new());
        let scene = Scene {
            cloth,
            ..Scene::default()
        };
        assert!(scene.validate().is_err());
    }
}
