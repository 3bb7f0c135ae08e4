/*
 * oiio_module.cpp — finds and loads libedgewise_oiio.so (oiio_codec.cpp) the
 * first time a file that is not an EXR is read or written.
 *
 * The module lies beside the library this code is linked into (build/lib
 * beside libedgewise_nodes.so, the installed lib directory, the Blender
 * add-on's package), or in ../lib from a program in bin/ (the tests and tools
 * that link ewio statically): looked up from where this code was loaded,
 * never from the build tree a copy was made in.
 */
#include "codec.h"

#include <atomic>
#include <climits>
#include <cstring>
#include <cstdlib>
#include <mutex>

#include <dlfcn.h>
#include <unistd.h>

namespace ewio {
namespace {

std::once_flag g_once;
std::atomic<const Codec *> g_codec{nullptr};
std::string g_why;

std::string dir_of(const std::string &p) {
    const size_t s = p.rfind('/');
    return s == std::string::npos ? std::string(".") : s == 0 ? std::string("/") : p.substr(0, s);
}

[[maybe_unused]] void load() {
    std::vector<std::string> dirs;
    Dl_info info;
    if (dladdr(reinterpret_cast<void *>(&oiio_codec), &info) && info.dli_fname && *info.dli_fname) {
        const std::string self = info.dli_fname;
        dirs.push_back(dir_of(self));
        dirs.push_back(dir_of(self) + "/../lib");
        char real[PATH_MAX];
        if (realpath(self.c_str(), real)) {
            dirs.push_back(dir_of(real));
            dirs.push_back(dir_of(real) + "/../lib");
        }
    }
    /* linked into the program itself, dladdr names it as it was invoked
     * (through $PATH: no directory at all): the kernel's name for it then */
    char exe[PATH_MAX];
    const ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n > 0) {
        exe[n] = '\0';
        dirs.push_back(dir_of(exe));
        dirs.push_back(dir_of(exe) + "/../lib");
    }
    std::string tried;
    for (const std::string &d : dirs) {
        const std::string p = d + "/libedgewise_oiio.so";
        void *h = dlopen(p.c_str(), RTLD_NOW | RTLD_LOCAL);
        if (!h) {
            const char *e = dlerror();
            /* a module that exists but does not load says why; a missing one is only listed */
            if (e && !std::strstr(e, "No such file")) {
                g_why = "cannot load " + p + ": " + e;
                return;
            }
            tried += (tried.empty() ? "" : ", ") + d;
            continue;
        }
        auto entry = reinterpret_cast<const Codec *(*)(void)>(dlsym(h, "ewio_oiio_codec"));
        if (!entry) {
            g_why = p + " has no entry point ewio_oiio_codec";
            return;
        }
        const Codec *c = entry();
        c->set_threads(io_threads());
        g_codec.store(c);
        return;
    }
    g_why = "libedgewise_oiio.so (the OpenImageIO reader and writer of formats other than EXR) was not found in " +
            tried;
}

} // namespace

const Codec *oiio_codec(std::string &why) {
#ifdef EW_OIIO_LINKED /* a sanitizer build (nodes/io/CMakeLists.txt says why) */
    std::call_once(g_once, [] {
        const Codec *c = ewio_oiio_codec();
        c->set_threads(io_threads());
        g_codec.store(c);
    });
#else
    std::call_once(g_once, load);
#endif
    const Codec *c = g_codec.load();
    if (!c) why = g_why;
    return c;
}

const Codec *oiio_codec_loaded() { return g_codec.load(); }

} // namespace ewio
