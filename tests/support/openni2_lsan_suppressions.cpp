// LeakSanitizer suppressions for the test executables that load OpenNI2 (a source of each such
// executable, not of the support library: nothing references this symbol, so an archive member
// would never be linked in).
//
// OpenNI2 2.2.0.33 and its drivers leak on their own (sensor info lists the OniFile driver
// allocates for every getSensorInfo and nobody frees, per-stream JPEG decoders, DummyDevice
// frame cookies, PS1080 and PSLink driver start-up); these suppressions name those modules only.
// mixray and the freenect plug-in allocate nothing from OpenNI2's threads, so their own leaks
// are still reported.
#if defined(__SANITIZE_ADDRESS__)
extern "C" const char* __lsan_default_suppressions() {
    return "leak:libOpenNI2.so\nleak:libOniFile.so\nleak:libDummyDevice.so\nleak:libPS1080.so\n"
           "leak:libPSLink.so\nleak:libjpeg.so\n";
}
#endif
