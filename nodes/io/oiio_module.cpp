/*
 * oiio_module.cpp — finds and loads libedgewise_oiio.so (oiio_codec.cpp) the
 * first time a file that is not an EXR is read or written.
 *
 * The module lies beside the library or program this code is linked into
 * (build/lib beside libedgewise_nodes.so, the installed lib directory), or
 * in ../lib from a program in bin/; a program linking ewio statically from
 * the build tree (tests, tools) also finds it in the build's lib directory.
 */
#include "codec.h"

#include <atomic>
#include <climits>
#include <cstring>
#include <cstdlib>
#include <mutex>

#include <dlfcn.h>

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
#ifdef EW_OIIO_MODULE_DIRS
    /* the build's and the install's lib directories, ':'-separated */
    const std::string more = EW_OIIO_MODULE_DIRS;
    for (size_t b = 0; b <= more.size();) {
        size_t e = more.find(':', b);
        if (e == std::string::npos) e = more.size();
        if (e > b) dirs.push_back(more.substr(b, e - b));
        b = e + 1;
    }
#endif
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
