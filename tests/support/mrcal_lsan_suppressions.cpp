// LeakSanitizer suppressions for the test executables that run mrcal's optimiser (a source of
// each such executable, for the reason given in openni2_lsan_suppressions.cpp).
//
// libdogleg 0.15.4, under mrcal_optimize, leaks its solver context when mrcal rejects outliers
// and optimises again ("Threw out some outliers ... going again"); only that module is named.
#if defined(__SANITIZE_ADDRESS__)
extern "C" const char* __lsan_default_suppressions() {
    return "leak:libdogleg.so\n";
}
#endif
