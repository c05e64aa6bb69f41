/* Preloaded (LD_PRELOAD) into the sanitizer test runs only, by scripts/sanitize.sh; never linked
 * into gsd.
 *
 * LeakSanitizer looks for leaks at process exit. By then the Vulkan loader has dlclose'd the
 * driver (Mesa's lavapipe), and a block the driver still holds through one of its own globals
 * loses its only reference when the driver's data segment is unmapped: LeakSanitizer reports it
 * as a leak from "<unknown module>", which no suppression can match, and turns every exit code
 * into a failure. With dlclose a no-op every library stays mapped until exit, its globals stay
 * roots, and that block is reachable, as it is in any normal run. Nothing is suppressed, so a
 * block gsd loses is still reported. */
int dlclose(void* handle) {
    (void)handle;
    return 0;
}
