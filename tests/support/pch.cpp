// The translation unit that compiles the test executables' shared precompiled header (tests/CMakeLists.txt,
// cmake/BuildSpeed.cmake). It holds nothing else.
