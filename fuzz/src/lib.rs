//! Parser fuzzing harness (see tests/).
