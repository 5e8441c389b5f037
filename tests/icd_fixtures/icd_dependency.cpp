// A library the fake driver below depends on; the build keeps it where the dynamic linker does not
// look (tests/CMakeLists.txt), as libGLdispatch was absent for NVIDIA's driver on the H100 machine.
extern "C" int voxtier_test_icd_dependency() {
    return 42;
}
