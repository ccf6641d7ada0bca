// The translation unit that compiles the test programs' precompiled header
// (skintune_test_pch in tests/CMakeLists.txt); it has no code of its own.
