/*
 * glibc_compat.h — force-included (-include) into libedgewise and the OFX
 * bundle when EW_GLIBC_COMPAT=ON: binds the glibc functions whose default
 * symbol version is newer than 2.28 (Debian 12 builds against 2.36) to the
 * versions every glibc since 2.17 has, so the binaries load on RHEL/Rocky 8
 * (glibc 2.28, the VFX Reference Platform's floor).
 *
 * - pthread_* and dl*: moved into libc in 2.34 and given GLIBC_2.34 as their
 *   default version; the old versions are still exported (and, on older
 *   glibcs, defined in libpthread / libdl, which the option links too).
 * - exp, exp2, log, log2, pow: 2.29 gave them new default versions (no
 *   SVID error handling); the old ones compute the same results.
 * tests/glibc/test_glibc_versions.sh lists what the built binaries import.
 */
#ifndef EW_GLIBC_COMPAT_H
#define EW_GLIBC_COMPAT_H
#if defined(__GLIBC__) || defined(__linux__)
#if defined(__x86_64__)
#define EW_GLIBC_BASE "GLIBC_2.2.5"
#elif defined(__aarch64__)
#define EW_GLIBC_BASE "GLIBC_2.17"
#endif
#ifdef EW_GLIBC_BASE
#define EW_GLIBC_OLD(sym) __asm__(".symver " #sym "," #sym "@" EW_GLIBC_BASE);
EW_GLIBC_OLD(pthread_create)
EW_GLIBC_OLD(pthread_join)
EW_GLIBC_OLD(pthread_detach)
EW_GLIBC_OLD(pthread_once)
EW_GLIBC_OLD(pthread_key_create)
EW_GLIBC_OLD(pthread_key_delete)
EW_GLIBC_OLD(pthread_getspecific)
EW_GLIBC_OLD(pthread_setspecific)
EW_GLIBC_OLD(pthread_mutex_trylock)
EW_GLIBC_OLD(pthread_mutexattr_init)
EW_GLIBC_OLD(pthread_mutexattr_destroy)
EW_GLIBC_OLD(pthread_mutexattr_settype)
EW_GLIBC_OLD(pthread_attr_setstacksize)
EW_GLIBC_OLD(pthread_sigmask)
EW_GLIBC_OLD(dlopen)
EW_GLIBC_OLD(dlclose)
EW_GLIBC_OLD(dlsym)
EW_GLIBC_OLD(dlerror)
EW_GLIBC_OLD(exp)
EW_GLIBC_OLD(exp2)
EW_GLIBC_OLD(log)
EW_GLIBC_OLD(log2)
EW_GLIBC_OLD(pow)
#undef EW_GLIBC_OLD
#endif
#endif
#endif
