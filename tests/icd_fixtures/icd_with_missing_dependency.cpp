// A stand-in Vulkan driver library (tests/icd_diagnosis_test.cpp): it loads only where its
// dependency is found, and the build leaves it no run-time path to that dependency, so neither
// the Vulkan loader nor voxtier's diagnosis can load it.
extern "C" int voxtier_test_icd_dependency();

// Were it ever loaded, it would refuse the loader (VK_ERROR_INCOMPATIBLE_DRIVER).
extern "C" int vk_icdNegotiateLoaderICDInterfaceVersion(unsigned* version) {
    *version = unsigned(voxtier_test_icd_dependency());
    return -9;
}
