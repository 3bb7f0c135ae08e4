/*
 * ewio.cpp — the image model behind ewio.h and everything around a file:
 * limits, channel naming, metadata, temporaries, the written file's check
 * and the atomic rename. The pixels and headers of a format are a codec's
 * (codec.h): OpenEXR's own library for EXR, the OpenImageIO module for the
 * rest. Rules kept throughout:
 *   - no exception leaves an extern "C" function (each body is wrapped);
 *   - nothing is printed, nothing exits;
 *   - a failing call leaves its outputs untouched (ewio_read returns no
 *     partial file, ewio_write leaves the destination as it was);
 *   - no global mutable state but the temporaries' table (for a signal
 *     handler) and the I/O thread count.
 */
#include "ewio.h"
#include "codec.h"
#include "exr_header_scan.h"
#include "exr_zip.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <strings.h>
#include <limits>
#include <map>
#include <memory>
#include <new>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace {

using ewio::Attr;
using ewio::BandDst;
using ewio::Codec;
using ewio::PixType;
using ewio::band_rows_of;
using ewio::first_line;
using ewio::one_line;
using ewio::reads_as;

constexpr long long kMaxSide = 65536;
constexpr long long kMaxPixels = 1LL << 28;
constexpr int kMaxChannels = 4096;

/* An allocator that leaves new floats uninitialised: a plane is sized from
 * the header before its pixels are read, and zero-filling it would make the
 * whole declared image resident at once — before a truncated file fails on
 * its first scan line. Every float is written before it is read. */
template <class T> struct NoInit : std::allocator<T> {
    template <class U> struct rebind { using other = NoInit<U>; };
    NoInit() = default;
    template <class U> NoInit(const NoInit<U> &) noexcept {}
    template <class U, class... A> void construct(U *p, A &&...a) {
        if constexpr (sizeof...(A) == 0) ::new (static_cast<void *>(p)) U;
        else ::new (static_cast<void *>(p)) U(std::forward<A>(a)...);
    }
};
using Plane = std::vector<float, NoInit<float>>;

struct Channel {
    std::string name, layer, pass, comp;
    PixType type = PixType::HALF; /* the type it was read with (half for new channels) */
    Plane px; /* width*height, row-major */
    /* Left in the source file (ewio_open): px is empty and the pixels are
     * decoded from channel part_ch of part `part` when they are asked for
     * or written. A channel with neither pixels nor on_disk was released. */
    bool on_disk = false;
    /* The source (a scanline EXR) holds the values this channel was read
     * with, as channel part_ch of part `part`, whatever it holds now. */
    bool in_src = false;
    int part = 0, part_ch = 0;
    /* Lent by the caller (ewio_lend_pass): pixel i is lent[i * lent_stride]
     * in the caller's buffer, px is empty. */
    const float *lent = nullptr;
    size_t lent_stride = 0;
};

/* Whether c holds its pixels in memory (a plane of its own or a lent
 * buffer); else they are on disk or were released. */
bool in_memory(const Channel &c, size_t npix) { return c.lent || c.px.size() == npix; }

/* Where c's pixels are in memory: pixel i at [i * *stride]. */
const float *memory_pixels(const Channel &c, size_t *stride) {
    *stride = c.lent ? c.lent_stride : 1;
    return c.lent ? c.lent : c.px.data();
}

/* c's pixels, once they are elsewhere (a plane, the source, released):
 * nothing of the caller's is pointed at any more. */
void unlend(Channel &c) {
    c.lent = nullptr;
    c.lent_stride = 0;
}

} // namespace

struct ewio_file {
    int width = 0, height = 0;
    /* Data/display window origin and display size, kept for EXR output. */
    int x = 0, y = 0, full_x = 0, full_y = 0, full_width = 0, full_height = 0;
    std::vector<Channel> ch;
    std::vector<std::string> layers;
    std::vector<Attr> attribs; /* the header's metadata, as OpenEXR stores it */
    std::map<std::string, std::string> attr_text; /* name -> text, for ewio_get_attribute */
    std::string exr_compression; /* "" = default (zip) */
    bool has_src = false;
    bool src_exr = false; /* the source is an EXR (its channels decode through OpenEXR) */
    dev_t src_dev = 0;
    ino_t src_ino = 0;
    std::string src_real; /* realpath() of the source, "" if unknown */
    /* What the source was when it was read, for channels left on disk:
     * they are decoded from it only while it is still that file. */
    std::string src_path, src_name; /* to open; as given, for messages */
    off_t src_size = 0;
    struct timespec src_mtime = {0, 0};
};

namespace {

/* ---------------------------------------------------------------- errors */

void set_err(char *err, size_t errlen, const std::string &msg) noexcept {
    if (!err || errlen == 0) return;
    size_t n = std::min(msg.size(), errlen - 1);
    memcpy(err, msg.data(), n);
    err[n] = '\0';
    for (size_t i = 0; i < n; i++)
        if (err[i] == '\n' || err[i] == '\r') err[i] = ' ';
}

void clear_err(char *err, size_t errlen) noexcept {
    if (err && errlen) err[0] = '\0';
}

std::string q(const std::string &s) { return "'" + s + "'"; }

std::string errno_text(int e) {
    switch (e) {
    case ENOENT: return "no such file or directory";
    case EACCES:
    case EPERM: return "permission denied";
    case EROFS: return "read-only file system";
    case ENOSPC: return "no space left on device";
    case EDQUOT: return "disk quota exceeded";
    case ENOTDIR: return "a path component is not a directory";
    case EISDIR: return "is a directory";
    case EFBIG: return "file too large";
    default: break;
    }
    char buf[256];
    buf[0] = '\0';
#ifdef _GNU_SOURCE /* GNU strerror_r may return a static string instead of filling buf */
    const char *r = strerror_r(e, buf, sizeof buf);
    return r ? std::string(r) : "error " + std::to_string(e);
#else
    if (strerror_r(e, buf, sizeof buf) != 0) return "error " + std::to_string(e);
    return buf;
#endif
}

/* ------------------------------------------------------- channel naming */

/* Blender's split (imb_exr_split_channel_name): the component follows the
 * last '.', the pass is the token before it, the layer is everything before
 * that. "ViewLayer.001.Combined.R" -> layer "ViewLayer.001" (Blender's name
 * for a second view layer), pass "Combined", comp "R". "Combined.R" -> layer
 * "", pass "Combined". "R" -> layer "", pass "". */
void split_name(const std::string &name, std::string &layer, std::string &pass,
                std::string &comp) {
    size_t last = name.rfind('.');
    if (last == std::string::npos) {
        layer.clear();
        pass.clear();
        comp = name;
        return;
    }
    comp = name.substr(last + 1);
    std::string rest = name.substr(0, last);
    size_t p = rest.rfind('.');
    if (p == std::string::npos) {
        layer.clear();
        pass = rest;
    } else {
        layer = rest.substr(0, p);
        pass = rest.substr(p + 1);
    }
}

std::string join_name(const std::string &layer, const std::string &pass,
                      const std::string &comp) {
    std::string n;
    if (!layer.empty()) n = layer + ".";
    if (!pass.empty() || !layer.empty()) n += pass + ".";
    return n + comp;
}

std::string display_pass(const std::string &layer, const std::string &pass) {
    return "layer " + q(layer) + " pass " + q(pass);
}

void rebuild_layers(ewio_file &f) {
    std::vector<std::string> l;
    for (const Channel &c : f.ch)
        if (std::find(l.begin(), l.end(), c.layer) == l.end()) l.push_back(c.layer);
    f.layers.swap(l);
}

std::string layers_found(const ewio_file &f) {
    if (f.layers.empty()) return "layers found: none (the file has no channels)";
    std::string s = "layers found: ";
    for (size_t i = 0; i < f.layers.size(); i++) {
        if (i) s += ", ";
        s += q(f.layers[i]);
    }
    return s;
}

std::string passes_of(const ewio_file &f, const std::string &layer) {
    std::vector<std::string> p;
    for (const Channel &c : f.ch)
        if (c.layer == layer && std::find(p.begin(), p.end(), c.pass) == p.end())
            p.push_back(c.pass);
    std::string s;
    for (size_t i = 0; i < p.size(); i++) {
        if (i) s += ", ";
        s += q(p[i]);
    }
    return s;
}

std::string comps_of(const ewio_file &f, const std::string &layer, const std::string &pass) {
    std::string s;
    for (const Channel &c : f.ch)
        if (c.layer == layer && c.pass == pass) {
            if (!s.empty()) s += ",";
            s += c.comp;
        }
    return s;
}

int find_channel(const ewio_file &f, const std::string &layer, const std::string &pass,
                 const std::string &comp) {
    for (size_t i = 0; i < f.ch.size(); i++) {
        const Channel &c = f.ch[i];
        if (c.comp == comp && c.pass == pass && c.layer == layer) return int(i);
    }
    return -1;
}

/* 1 when every component of the pass is a channel of the file for which
 * `ok` holds (0 for a NULL file or empty comps) */
template <class Ok> int every_channel(const ewio_file *f, const char *layer, const char *pass, const char *comps, Ok ok) {
    if (!f || !comps || !*comps) return 0;
    try {
        const std::string L = layer ? layer : "", P = pass ? pass : "";
        for (const char *c = comps; *c; c++) {
            const int i = find_channel(*f, L, P, std::string(1, *c));
            if (i < 0 || !ok(f->ch[size_t(i)])) return 0;
        }
        return 1;
    } catch (...) {
        return 0;
    }
}

bool has_layer(const ewio_file &f, const std::string &layer) {
    return std::find(f.layers.begin(), f.layers.end(), layer) != f.layers.end();
}

bool has_any_pass(const ewio_file &f, const std::string &layer, const std::string &pass) {
    for (const Channel &c : f.ch)
        if (c.layer == layer && c.pass == pass) return true;
    return false;
}

/* Message for a pass lacking components `missing` (all of `comps` if the
 * pass is absent). Always names what is missing and lists the layers. */
std::string missing_msg(const ewio_file &f, const std::string &layer, const std::string &pass,
                        const std::string &comps, const std::string &missing) {
    std::string m;
    if (!has_layer(f, layer)) {
        m = "missing " + display_pass(layer, pass) + " (components " + q(comps) + "): no layer " +
            q(layer) + " in the file";
    } else if (!has_any_pass(f, layer, pass)) {
        m = "missing " + display_pass(layer, pass) + " (components " + q(comps) +
            "): layer " + q(layer) + " has passes " + passes_of(f, layer);
    } else {
        m = "missing components " + q(missing) + " of " + display_pass(layer, pass) +
            " (it has " + comps_of(f, layer, pass) + ")";
    }
    return m + "; " + layers_found(f);
}

/* The channels of pass (L, P)'s components C, in C's order, into idx (-1
 * where absent); "" when all exist, else the message naming the missing. */
std::string pass_channels(const ewio_file &f, const std::string &L, const std::string &P, const std::string &C,
                          std::vector<int> &idx) {
    std::string missing;
    idx.clear();
    for (char c : C) {
        const int i = find_channel(f, L, P, std::string(1, c));
        if (i < 0) missing += c;
        idx.push_back(i);
    }
    return missing.empty() ? std::string() : missing_msg(f, L, P, C, missing);
}

/* ------------------------------------------------------------ dimensions */

std::string gib(unsigned long long bytes) {
    char b[64];
    snprintf(b, sizeof b, "%.1f GiB", double(bytes) / double(1ULL << 30));
    return b;
}

unsigned long long physical_memory() {
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? (unsigned long long)pages * (unsigned long long)page : 0;
}

std::string check_dims(long long w, long long h) {
    if (w <= 0 || h <= 0)
        return "invalid image dimensions " + std::to_string(w) + "x" + std::to_string(h);
    const long long maxp = ewio_max_pixels();
    if (w > kMaxSide || h > kMaxSide)
        return "image too large: " + std::to_string(w) + "x" + std::to_string(h) +
               " (at most 65536 pixels per side)";
    if (w * h > maxp)
        return "image too large: " + std::to_string(w) + "x" + std::to_string(h) + " is " +
               std::to_string(w * h) + " pixels, above the limit of " + std::to_string(maxp) +
               " (--max-pixels or EDGEWISE_MAX_PIXELS raise it, up to 2^28)";
    return std::string();
}

/* What a whole read of the file holds: every channel of every part as
 * float, from the header alone (before anything is allocated). */
std::string check_bytes(long long w, long long h, long long channels) {
    const unsigned long long need = (unsigned long long)w * (unsigned long long)h *
                                    (unsigned long long)channels * sizeof(float);
    const unsigned long long lim = ewio_max_memory();
    if (lim && need > lim)
        return "the header declares " + std::to_string(w) + "x" + std::to_string(h) + " pixels x " +
               std::to_string(channels) + " channels = " + gib(need) +
               " as float, above the memory limit of " + gib(lim) +
               " (--max-memory or EDGEWISE_MAX_MEMORY raise it; the default is 3/4 of the "
               "physical memory)";
    return std::string();
}

/* An OpenEXR file's headers against its size and the limits, before
 * OpenEXR opens it ("" when plausible or not an EXR file); *is_exr: the file
 * starts with EXR's magic number. */
std::string exr_header_check(const char *path, long long size, bool *is_exr) {
    *is_exr = false;
    FILE *fp = fopen(path, "rbe");
    if (!fp) return std::string(); /* the open that follows reports it */
    ewio_exr_layout lay;
    char why[256];
    const int bad = ewio_exr_header_scan(fp, size, &lay, why, sizeof why);
    fclose(fp);
    *is_exr = lay.is_exr;
    if (bad) return why;
    if (!lay.is_exr) {
        /* OpenImageIO would try its every other reader on the bytes, some
         * of which allocate what a stray header declares (hundreds of MB
         * for a 93-byte file); a file named .exr is an EXR file or refused */
        const size_t n = std::strlen(path);
        if (n >= 4 && strcasecmp(path + n - 4, ".exr") == 0)
            return "not an image file OpenEXR can read: named .exr, but it does not start with EXR's magic number";
        return std::string();
    }
    if (lay.width == 0) return std::string();
    std::string d = check_dims(lay.width, lay.height);
    if (d.empty()) d = check_bytes(lay.width, lay.height, std::max(1LL, lay.channels));
    /* in 128 bits: a stray header's tile sides go up to 2^32 each */
    if (d.empty() && (__int128)lay.tile_width * lay.tile_height > (__int128)lay.width * lay.height) {
        d = check_dims(lay.tile_width, lay.tile_height);
        if (d.empty()) d = check_bytes(lay.tile_width, lay.tile_height, std::max(1LL, lay.channels));
        if (!d.empty()) d = "tiles larger than the image: " + d;
    }
    return d;
}

/* ----------------------------------------------------------- attributes */

void rebuild_attr_text(ewio_file &f) {
    f.attr_text.clear();
    for (const Attr &a : f.attribs) f.attr_text[a.name] = ewio::attr_text(a);
    if (!f.exr_compression.empty()) f.attr_text["compression"] = f.exr_compression;
}

Attr *find_attr(ewio_file &f, const std::string &n) {
    for (Attr &a : f.attribs)
        if (a.name == n) return &a;
    return nullptr;
}

/* ------------------------------------------------------------ file paths */

std::string dir_of(const std::string &path) {
    size_t s = path.rfind('/');
    if (s == std::string::npos) return ".";
    if (s == 0) return "/";
    return path.substr(0, s);
}

std::string base_of(const std::string &path) {
    size_t s = path.rfind('/');
    return s == std::string::npos ? path : path.substr(s + 1);
}

std::string lower_ext(const std::string &base) {
    size_t d = base.rfind('.');
    if (d == std::string::npos || d == 0 || d + 1 >= base.size()) return std::string();
    std::string e = base.substr(d + 1);
    for (char &c : e) c = char(tolower((unsigned char)c));
    return e;
}

std::string real_path(const std::string &p) {
    char *r = realpath(p.c_str(), nullptr);
    if (!r) return std::string();
    std::string s(r);
    free(r);
    return s;
}

/* Canonical form of a path that may not exist yet: realpath of its
 * directory plus its base name. */
std::string canonical_target(const std::string &path) {
    std::string r = real_path(path);
    if (!r.empty()) return r;
    std::string d = real_path(dir_of(path));
    if (d.empty()) return std::string();
    return (d == "/" ? d : d + "/") + base_of(path);
}

/* Temporaries being written, so that ewio_remove_temporaries() can delete
 * them from a signal handler (SIGINT/SIGTERM during a write). This table is
 * the shim's one piece of process-wide mutable state: a signal handler has
 * nothing else to reach. Slots are claimed with atomics and the handler
 * only reads them and calls unlink(), both async-signal-safe. */
constexpr int kTempSlots = 32;
struct TempSlot {
    std::atomic<int> state{0}; /* 0 free, 1 claimed (path being set), 2 armed */
    char path[4096];
};
TempSlot g_temps[kTempSlots];

/* Removes the temporary file unless released. */
struct TempGuard {
    std::string path;
    bool armed = false;
    int slot = -1;
    /* A slot armed with the mkostemps template `name`, whose buffer mkostemps
     * is then given: it writes each name it tries there before it creates
     * the file, so a signal that comes at any moment after the file exists
     * finds it (arming after mkostemps returned left a window in which the
     * file existed unlisted: a SIGINT there left it behind). Before that the
     * handler unlinks a name that does not exist yet. NULL when the name
     * does not fit a slot or all are taken: the file is then removed by this
     * guard only, not on a signal. */
    char *claim(const std::string &name) {
        if (name.size() >= sizeof g_temps[0].path) return nullptr;
        for (int i = 0; i < kTempSlots; i++) {
            int expected = 0;
            if (g_temps[i].state.compare_exchange_strong(expected, 1)) {
                memcpy(g_temps[i].path, name.c_str(), name.size() + 1);
                g_temps[i].state.store(2);
                slot = i;
                return g_temps[i].path;
            }
        }
        return nullptr;
    }
    /* The file at `p` now exists and is ours. */
    void arm(const char *p) {
        path.assign(p);
        armed = true;
    }
    /* Renamed into place (or never created): nothing to remove any more. */
    void release() {
        armed = false;
        if (slot >= 0) g_temps[slot].state.store(0);
        slot = -1;
    }
    ~TempGuard() {
        if (armed) unlink(path.c_str());
        release();
    }
};

/* The process's umask, read without changing it (umask() would set it for
 * every thread for a moment); -1 when the kernel does not say. */
int current_umask() {
    FILE *f = fopen("/proc/self/status", "re");
    if (!f) return -1;
    char line[256];
    int mask = -1;
    while (fgets(line, sizeof line, f))
        if (sscanf(line, "Umask: %o", (unsigned *)&mask) == 1) break;
    fclose(f);
    return mask;
}

/* Create a temporary beside `dir`/`base`: ".<base>.tmp-XXXXXX.<ext>" by
 * mkostemps, with base shortened when the whole would pass the 255-byte
 * name limit (an output name of 238-255 characters is itself fine). Its
 * mode is the destination's when one exists (dst_mode >= 0), else what
 * open(0666) would give, since mkostemps makes it 0600. Returns the open
 * descriptor and sets guard.path, or -1 with errno set. */
int make_temp(TempGuard &guard, const std::string &dir, const std::string &base, const std::string &ext,
              int dst_mode) {
    const std::string tail = ext.empty() ? "" : "." + ext;
    const size_t extra = 1 + 5 + 6 + tail.size();
    std::string b = base;
    if (b.size() + extra > 255) b.resize(extra < 255 ? 255 - extra : 0);
    std::string name = (dir == "/" ? std::string("/") : dir + "/") + "." + b + ".tmp-XXXXXX" + tail;
    std::vector<char> buf(name.begin(), name.end());
    buf.push_back('\0');
    char *tmpl = guard.claim(name);
    if (!tmpl) tmpl = buf.data();
    const int fd = mkostemps(tmpl, int(tail.size()), O_CLOEXEC);
    if (fd < 0) {
        const int e = errno;
        guard.release();
        errno = e;
        return -1;
    }
    guard.arm(tmpl);
    int mode = dst_mode;
    if (mode < 0) {
        const int mask = current_umask();
        mode = mask < 0 ? -1 : 0666 & ~mask;
    }
    if (mode >= 0) (void)fchmod(fd, mode_t(mode));
    return fd;
}

/* ------------------------------------------------------------------ read */

/* hdr non-NULL: stop after the header checks, with its figures in *hdr. */
int read_impl(const char *path, ewio_file **out, std::string &msg, ewio_header *hdr = nullptr, bool defer = false) {
    const std::string p(path);
    struct stat st;
    if (stat(path, &st) != 0) {
        int e = errno;
        if (e == ENOENT || e == ENOTDIR)
            msg = "cannot read " + q(p) + ": no such file";
        else
            msg = "cannot read " + q(p) + ": " + errno_text(e);
        return 1;
    }
    if (S_ISDIR(st.st_mode)) {
        msg = "cannot read " + q(p) + ": is a directory";
        return 1;
    }
    if (!S_ISREG(st.st_mode)) {
        msg = "cannot read " + q(p) + ": not a regular file";
        return 1;
    }
    if (access(path, R_OK) != 0) {
        msg = "cannot read " + q(p) + ": " + errno_text(errno);
        return 1;
    }

    /* OpenEXR allocates what its headers declare while opening; what the
     * file cannot hold, or the limits refuse, stops here first. */
    bool is_exr = false;
    std::string d = exr_header_check(path, (long long)st.st_size, &is_exr);
    if (!d.empty()) {
        msg = "cannot read " + q(p) + ": " + d;
        return 1;
    }

    const Codec *codec = &ewio::exr_codec();
    std::string why;
    if (!is_exr && !(codec = ewio::oiio_codec(why))) {
        msg = "cannot read " + q(p) + ": not an OpenEXR file, and " + why;
        return 1;
    }
    std::unique_ptr<ewio::Reader> in = codec->open_reader(p, why);
    if (!in) {
        msg = "cannot read " + q(p) + ": not an image file or unsupported format (" +
              (why.empty() ? std::string("no reader accepted it") : why) + ")";
        return 1;
    }
    const std::vector<ewio::PartHeader> &parts = in->parts();
    if (parts.empty()) {
        msg = "cannot read " + q(p) + ": not an image file or unsupported format (no image in it)";
        return 1;
    }

    std::unique_ptr<ewio_file> f(new ewio_file);
    const ewio::PartHeader &s0 = parts[0];
    if (s0.deep) {
        msg = "cannot read " + q(p) + ": deep images are not supported";
        return 1;
    }
    if (s0.volume) {
        msg = "cannot read " + q(p) + ": volume (3D) images are not supported";
        return 1;
    }
    d = check_dims(s0.width, s0.height);
    if (!d.empty()) {
        msg = "cannot read " + q(p) + ": " + d;
        return 1;
    }
    f->width = int(s0.width);
    f->height = int(s0.height);
    f->x = s0.x;
    f->y = s0.y;
    f->full_x = s0.full_x;
    f->full_y = s0.full_y;
    f->full_width = s0.full_width > 0 && s0.full_width <= INT32_MAX ? int(s0.full_width) : f->width;
    f->full_height = s0.full_height > 0 && s0.full_height <= INT32_MAX ? int(s0.full_height) : f->height;
    const size_t npix = size_t(s0.width) * size_t(s0.height);

    /* Every part's header before any pixel memory: a part that cannot be
     * kept beside the first (another size or origin, deep, 3D) refuses the
     * file with the reason rather than silently leaving that part out of
     * the output, and the whole read is checked against the memory limit. */
    long long total_channels = 0;
    for (size_t sub = 0; sub < parts.size(); sub++) {
        const ewio::PartHeader &s = parts[sub];
        const std::string part = "part " + std::to_string(sub + 1) + (s.name.empty() ? "" : " " + q(s.name));
        if (sub > 0 && (s.deep || s.volume)) {
            msg = "cannot read " + q(p) + ": " + part + " is a " + (s.deep ? "deep" : "volume (3D)") +
                  " image, which is not supported";
            return 1;
        }
        if (sub > 0 && (s.width != s0.width || s.height != s0.height || s.x != s0.x || s.y != s0.y)) {
            msg = "cannot read " + q(p) + ": " + part + " is " + std::to_string(s.width) + "x" +
                  std::to_string(s.height) + " at (" + std::to_string(s.x) + "," + std::to_string(s.y) +
                  ") but part 1 is " + std::to_string(s0.width) + "x" + std::to_string(s0.height) +
                  " at (" + std::to_string(s0.x) + "," + std::to_string(s0.y) +
                  "): parts of different sizes or origins are not supported (the output keeps every "
                  "layer in one part); extract the parts first";
            return 1;
        }
        if (!s.problem.empty()) {
            msg = "cannot read " + q(p) + ": " + (parts.size() > 1 ? part + ": " : std::string()) + s.problem;
            return 1;
        }
        total_channels += (long long)s.channels.size();
        if (total_channels > kMaxChannels) {
            msg = "cannot read " + q(p) + ": too many channels (limit " + std::to_string(kMaxChannels) + ")";
            return 1;
        }
    }
    d = check_bytes(s0.width, s0.height, total_channels);
    if (!d.empty()) {
        msg = "cannot read " + q(p) + ": " + d;
        return 1;
    }
    f->attribs = in->attributes();
    if (hdr) {
        hdr->width = f->width;
        hdr->height = f->height;
        hdr->channels = int(total_channels);
        /* the render's sample count when every layer's agrees */
        long long spp = 0;
        for (const Attr &a : f->attribs) {
            const std::string &nm = a.name;
            if (nm.compare(0, 7, "cycles.") != 0 || nm.size() < 15 || nm.compare(nm.size() - 8, 8, ".samples") != 0)
                continue;
            const std::string v = ewio::attr_text(a);
            char *end = nullptr;
            errno = 0;
            long long k = strtoll(v.c_str(), &end, 10);
            if (end == v.c_str() || errno == ERANGE || k <= 0) k = 0;
            if (k > (1LL << 24)) k = 1LL << 24;
            spp = spp == 0 || spp == k ? k : -1;
        }
        hdr->samples = spp > 0 ? int(spp) : 0;
        return 0;
    }

    /* Parts: multi-part EXR parts of the same size and origin are merged. */
    for (size_t sub = 0; sub < parts.size(); sub++) {
        const ewio::PartHeader &s = parts[sub];
        const int nch = int(s.channels.size());
        if (nch <= 0) {
            if (sub == 0) {
                msg = "cannot read " + q(p) + ": the image has no channels";
                return 1;
            }
            continue;
        }
        const size_t first = f->ch.size();
        for (int c = 0; c < nch; c++) {
            Channel ch;
            ch.name = s.channels[size_t(c)];
            if (ch.name.empty()) ch.name = "channel" + std::to_string(c);
            bool dup = false;
            for (const Channel &o : f->ch) dup = dup || o.name == ch.name;
            if (dup && sub > 0 && !s.name.empty()) {
                ch.name = s.name + "." + ch.name;
                dup = false;
                for (const Channel &o : f->ch) dup = dup || o.name == ch.name;
            }
            if (dup) {
                msg = "cannot read " + q(p) + ": duplicate channel name " + q(ch.name);
                return 1;
            }
            split_name(ch.name, ch.layer, ch.pass, ch.comp);
            ch.type = s.types[size_t(c)];
            ch.part = int(sub);
            ch.part_ch = c;
            f->ch.push_back(std::move(ch));
        }
        /* A scanline EXR part's pixels can be decoded later, channel by
         * channel and band by band: ewio_open leaves them in the file. */
        if (is_exr && s.decodes_later)
            for (size_t c = first; c < f->ch.size(); c++) f->ch[c].in_src = true;
        if (defer && is_exr && s.decodes_later) {
            for (size_t c = first; c < f->ch.size(); c++) f->ch[c].on_disk = true;
            continue;
        }
        for (size_t c = first; c < f->ch.size(); c++) f->ch[c].px.resize(npix);

        const size_t w = size_t(s.width);
        std::vector<int> chans(static_cast<size_t>(nch));
        std::vector<BandDst> band(static_cast<size_t>(nch));
        for (int c = 0; c < nch; c++) chans[size_t(c)] = c;
        /* a tiled part in one band: the codec assembles the tiles */
        const size_t rows = s.tiled ? size_t(s.height) : band_rows_of(w * size_t(nch) * sizeof(float), size_t(s.height));
        for (long long y0 = 0; y0 < s.height; y0 += (long long)rows) {
            const long long y1 = std::min<long long>(s.height, y0 + (long long)rows);
            for (int c = 0; c < nch; c++)
                band[size_t(c)] = BandDst{f->ch[first + size_t(c)].px.data() + size_t(y0) * w, 1, w};
            if (!in->read(int(sub), int(y0), int(y1), chans.data(), band.data(), band.size(), why)) {
                msg = "cannot read " + q(p) + ": corrupt or truncated image data (" + why + ")";
                return 1;
            }
        }
    }
    /* (the codec's metadata leaves out what describes the file's layout
     * rather than the image: the output is always one part, chunked by its
     * writer) */
    if (is_exr) f->exr_compression = in->compression();
    in.reset();
    rebuild_attr_text(*f);
    rebuild_layers(*f);

    f->has_src = true;
    f->src_exr = is_exr;
    f->src_dev = st.st_dev;
    f->src_ino = st.st_ino;
    f->src_real = real_path(p);
    f->src_path = f->src_real.empty() ? p : f->src_real;
    f->src_name = p;
    f->src_size = st.st_size;
    f->src_mtime = st.st_mtim;
    *out = f.release();
    return 0;
}

/* ------------------------------------------------- channels left on disk */

/* Decodes channels that ewio_open left in the source file, band by band of
 * rows, converted to float as read_impl converts them (OpenEXR's own
 * conversion of the stored type): what comes out is what an ewio_read
 * would have held. Refuses a source that is no longer the file that was
 * read (another inode, size or modification time). */
class SourceReader {
  public:
    bool open(const ewio_file &f, const std::vector<int> &chans, std::string &why) {
        file_ = &f;
        const std::string &p = f.src_path;
        struct stat a, b;
        std::string err;
        const bool before = f.src_exr && stat(p.c_str(), &a) == 0;
        if (before) in_ = ewio::exr_codec().open_reader(p, err);
        const bool after = in_ && stat(p.c_str(), &b) == 0;
        auto same = [&](const struct stat &s) {
            return s.st_dev == f.src_dev && s.st_ino == f.src_ino && s.st_size == f.src_size &&
                   s.st_mtim.tv_sec == f.src_mtime.tv_sec && s.st_mtim.tv_nsec == f.src_mtime.tv_nsec;
        };
        if (!before || !after || !same(a) || !same(b)) {
            why = "cannot read " + q(f.src_name) +
                  " again: it changed or went away since it was first read (the passes a command does not "
                  "use are read from it when they are written)";
            if (before && !in_) why += " (" + first_line(err, "cannot open it") + ")";
            in_.reset();
            return false;
        }
        const std::vector<ewio::PartHeader> &ps = in_->parts();
        for (size_t k = 0; k < chans.size(); k++) {
            const Channel &c = f.ch[size_t(chans[k])];
            if (c.part < 0 || size_t(c.part) >= ps.size() || ps[size_t(c.part)].width != f.width ||
                ps[size_t(c.part)].height != f.height || !ps[size_t(c.part)].decodes_later ||
                size_t(c.part_ch) >= ps[size_t(c.part)].channels.size()) {
                why = "cannot read " + q(f.src_name) + " again: it no longer has the layout it was first read with";
                return false;
            }
            Part *pt = nullptr;
            for (Part &q2 : parts_)
                if (q2.sub == c.part) pt = &q2;
            if (!pt) {
                parts_.push_back(Part());
                pt = &parts_.back();
                pt->sub = c.part;
            }
            pt->want.push_back(int(k));
            pt->chans.push_back(c.part_ch);
        }
        return true;
    }

    /* dst[k] (for chans[k]) receives rows y0..y1. */
    bool read(int y0, int y1, const BandDst *dst, std::string &why) {
        for (Part &pt : parts_) {
            pt.dst.clear();
            for (int k : pt.want) pt.dst.push_back(dst[k]);
            std::string e;
            if (!in_->read(pt.sub, y0, y1, pt.chans.data(), pt.dst.data(), pt.dst.size(), e)) {
                why = "cannot read " + q(file_->src_name) + ": corrupt or truncated image data (" + e + ")";
                return false;
            }
        }
        return true;
    }

    /* Every row, band by band: at[k] (for chans[k]) is where pixel (0, 0)
     * goes, with its strides. */
    bool read_all(const std::vector<BandDst> &at, std::string &why) {
        std::vector<BandDst> band(at);
        const int rows = band_rows(at.size());
        for (int y0 = 0; y0 < file_->height; y0 += rows) {
            for (size_t k = 0; k < at.size(); k++) band[k].p = at[k].p + size_t(y0) * at[k].ys;
            if (!read(y0, std::min(file_->height, y0 + rows), band.data(), why)) return false;
        }
        return true;
    }

    /* Rows of a band of n float channels: band_rows_of. */
    int band_rows(size_t n) const {
        return int(band_rows_of(size_t(file_->width) * n * sizeof(float), size_t(file_->height)));
    }

  private:
    struct Part {
        int sub = 0;
        std::vector<int> want;  /* indices into chans */
        std::vector<int> chans; /* their channels in the part */
        std::vector<BandDst> dst;
    };
    const ewio_file *file_ = nullptr;
    std::unique_ptr<ewio::Reader> in_;
    std::vector<Part> parts_;
};

/* ----------------------------------------------------------------- write */

enum class Kind { EXR, PNG, TIFF, JPEG };

/* EXR stores half, float and uint only. */
PixType exr_type(PixType t) {
    if (t == PixType::HALF || t == PixType::FLOAT || t == PixType::U32) return t;
    if (t == PixType::U8 || t == PixType::I8) return PixType::HALF;
    return PixType::FLOAT;
}

/* Whether the EXR written at `path` is a w x h image of nch channels with
 * all its pixel data (ewio_exr_chunks_check: its chunk table and every
 * chunk's place and size, no pixel decoded). OpenEXR encoded every chunk
 * from our floats and reports a failed write of one; what it does not report
 * is a failure writing the chunk table on close — and a file cut short — both
 * of which the check finds. A kind of file the check does not cover is
 * decoded whole (the codec's read_back). */
bool written_exr_ok(const std::string &path, int w, int h, int nch, std::string &why) {
    FILE *fp = fopen(path.c_str(), "rbe");
    struct stat st;
    if (!fp || fstat(fileno(fp), &st) != 0) {
        why = errno_text(errno);
        if (fp) fclose(fp);
        return false;
    }
    ewio_exr_layout lay;
    char buf[256];
    const int r = ewio_exr_chunks_check(fp, (long long)st.st_size, &lay, buf, sizeof buf);
    fclose(fp);
    if (r < 0) return ewio::exr_codec().read_back(path, w, h, nch, why);
    if (r > 0) {
        why = buf;
        return false;
    }
    if (lay.width != w || lay.height != h || lay.channels != nch) {
        why = reads_as(lay.width, lay.height, lay.channels);
        return false;
    }
    return true;
}

int write_impl(const ewio_file &f, const char *cpath, ewio_pixel_type type, const char *clayer,
               const char *cpass, std::string &msg) {
    const std::string path(cpath);
    const std::string base = base_of(path);
    const std::string dir = dir_of(path);
    const std::string what = "cannot write " + q(path) + ": ";
    if (base.empty() || base == "." || base == "..") {
        msg = what + "not a file name";
        return 1;
    }
    if (type != EWIO_KEEP && type != EWIO_HALF && type != EWIO_FLOAT) {
        msg = what + "invalid pixel type " + std::to_string(int(type));
        return 1;
    }
    const std::string ext = lower_ext(base);
    Kind kind;
    if (ext == "exr")
        kind = Kind::EXR;
    else if (ext == "png")
        kind = Kind::PNG;
    else if (ext == "tif" || ext == "tiff")
        kind = Kind::TIFF;
    else if (ext == "jpg" || ext == "jpeg")
        kind = Kind::JPEG;
    else {
        msg = what + (ext.empty() ? std::string("no file extension")
                                  : "unsupported extension " + q("." + ext)) +
              " (use .exr, .png, .tif, .tiff, .jpg or .jpeg)";
        return 1;
    }

    /* The destination must not be the file the data came from. */
    struct stat dst_st;
    const bool dst_exists = stat(path.c_str(), &dst_st) == 0;
    if (dst_exists && S_ISDIR(dst_st.st_mode)) {
        msg = what + "is a directory";
        return 1;
    }
    if (f.has_src) {
        bool same = dst_exists && dst_st.st_dev == f.src_dev && dst_st.st_ino == f.src_ino;
        if (!same && !f.src_real.empty()) same = canonical_target(path) == f.src_real;
        if (same) {
            msg = what + "refusing to overwrite the input file it was read from "
                         "(write to another path)";
            return 1;
        }
    }
    struct stat dir_st;
    if (stat(dir.c_str(), &dir_st) != 0) {
        int e = errno;
        msg = what + "directory " + q(dir) +
              (e == ENOENT ? std::string(" does not exist") : ": " + errno_text(e));
        return 1;
    }
    if (!S_ISDIR(dir_st.st_mode)) {
        msg = what + q(dir) + " is not a directory";
        return 1;
    }

    /* ---- what to write */
    const int w = f.width, h = f.height;
    std::vector<int> src;      /* channel index per output channel */
    std::vector<PixType> fmts; /* per output channel */
    std::vector<std::string> names;
    bool clamp01 = false;
    if (kind == Kind::EXR) {
        if (f.ch.empty()) {
            msg = what + "the image has no channels";
            return 1;
        }
        for (size_t i = 0; i < f.ch.size(); i++) {
            src.push_back(int(i));
            names.push_back(f.ch[i].name);
            fmts.push_back(type == EWIO_HALF    ? PixType::HALF
                           : type == EWIO_FLOAT ? PixType::FLOAT
                                                : exr_type(f.ch[i].type));
        }
    } else {
        const std::string layer = clayer ? clayer : "";
        const std::string pass = cpass ? cpass : "";
        auto idx = [&](const char *c) { return find_channel(f, layer, pass, c); };
        std::vector<int> pick;
        if (idx("R") >= 0 && idx("G") >= 0 && idx("B") >= 0) {
            pick = {idx("R"), idx("G"), idx("B")};
            if (kind != Kind::JPEG && idx("A") >= 0) pick.push_back(idx("A"));
        } else if (idx("X") >= 0 && idx("Y") >= 0 && idx("Z") >= 0) {
            pick = {idx("X"), idx("Y"), idx("Z")};
        } else {
            std::vector<int> all;
            for (size_t i = 0; i < f.ch.size(); i++)
                if (f.ch[i].layer == layer && f.ch[i].pass == pass) all.push_back(int(i));
            if (all.size() == 1) pick = all; /* a single channel: greyscale */
        }
        if (pick.empty()) {
            if (!has_any_pass(f, layer, pass))
                msg = what + missing_msg(f, layer, pass, "RGB", "RGB");
            else
                msg = what + display_pass(layer, pass) + " has components " +
                      comps_of(f, layer, pass) + ", which cannot be written as RGB(A)";
            return 1;
        }
        bool all8 = true, all16 = true;
        for (int i : pick) {
            all8 = all8 && f.ch[size_t(i)].type == PixType::U8;
            all16 = all16 && f.ch[size_t(i)].type == PixType::U16;
        }
        PixType t = PixType::U8;
        if (kind == Kind::PNG && type == EWIO_KEEP && all16) t = PixType::U16;
        if (kind == Kind::TIFF) {
            if (type == EWIO_HALF)
                t = PixType::HALF;
            else if (type == EWIO_FLOAT)
                t = PixType::FLOAT;
            else
                t = all8 ? PixType::U8 : all16 ? PixType::U16 : PixType::FLOAT;
        }
        clamp01 = t == PixType::U8 || t == PixType::U16;
        static const char *rgba[] = {"R", "G", "B", "A"};
        for (size_t k = 0; k < pick.size(); k++) {
            src.push_back(pick[k]);
            fmts.push_back(t);
            names.push_back(pick.size() == 1 ? std::string("Y") : std::string(rgba[k]));
        }
    }
    const int nch = int(src.size());
    std::vector<int> disk; /* output channels left in the source file */
    for (int c = 0; c < int(src.size()); c++)
        if (f.ch[size_t(src[size_t(c)])].on_disk) disk.push_back(c);
    for (int i : src)
        if (!f.ch[size_t(i)].on_disk && !in_memory(f.ch[size_t(i)], size_t(w) * size_t(h))) {
            msg = what + "the pixels of channel " + q(f.ch[size_t(i)].name) +
                  " were released (ewio_release_pass) and not set again";
            return 1;
        }

    ewio::WriteSpec spec;
    spec.width = w;
    spec.height = h;
    spec.names = names;
    spec.types = fmts;
    if (kind == Kind::EXR) {
        spec.x = f.x;
        spec.y = f.y;
        spec.full_x = f.full_x;
        spec.full_y = f.full_y;
        spec.full_width = f.full_width;
        spec.full_height = f.full_height;
        /* Metadata of another format's reader under its own prefix
         * ("png:", "tiff:"...) does not describe an EXR. */
        for (const Attr &a : f.attribs) {
            const size_t colon = a.name.find(':');
            const std::string prefix = colon == std::string::npos ? std::string() : a.name.substr(0, colon);
            static const char *const foreign[] = {"oiio", "png", "tiff", "jpeg", "openexr", "bmp", "gif", "targa"};
            bool skip = false;
            for (const char *fp : foreign) skip = skip || strcasecmp(prefix.c_str(), fp) == 0;
            if (!skip) spec.attrs.push_back(a);
        }
        spec.compression = f.exr_compression.empty() ? std::string("zip") : f.exr_compression;
    } else {
        spec.full_width = w;
        spec.full_height = h;
        spec.attrs = f.attribs; /* the codec keeps plain text */
    }

    const Codec *codec = &ewio::exr_codec();
    {
        std::string why;
        if (kind != Kind::EXR && !(codec = ewio::oiio_codec(why))) {
            msg = what + "no writer for " + q("." + ext) + " (" + why + ")";
            return 1;
        }
    }
    std::unique_ptr<ewio::Writer> out = codec->create_writer();

    /* ---- temporary file next to the destination */
    TempGuard guard;
    {
        const int fd = make_temp(guard, dir, base, ext,
                                 dst_exists && S_ISREG(dst_st.st_mode) ? int(dst_st.st_mode & 07777) : -1);
        const int e = errno;
        if (fd < 0) {
            if (e == EACCES || e == EPERM || e == EROFS)
                msg = what + "directory " + q(dir) + " is not writable (" + errno_text(e) + ")";
            else
                msg = what + "cannot create a temporary file in " + q(dir) + " (" +
                      errno_text(e) + ")";
            return 1;
        }
        close(fd);
    }

    /* the passes left in the source are decoded from it band by band */
    SourceReader disk_in;
    if (!disk.empty()) {
        std::vector<int> chans;
        for (int c : disk) chans.push_back(src[size_t(c)]);
        std::string why;
        if (!disk_in.open(f, chans, why)) {
            msg = what + why;
            return 1;
        }
    }
    {
        std::string why;
        if (!out->open(guard.path, spec, why)) {
            msg = what + why;
            return 1;
        }
    }
    {
        const size_t rows = size_t(disk.empty() ? band_rows_of(size_t(w) * size_t(nch) * sizeof(float), size_t(h))
                                                : size_t(disk_in.band_rows(size_t(nch))));
        /* channels in memory go to the codec where they are; the passes
         * decoded from the source, and values clamped for 8 and 16 bits,
         * through planes of a band (each float written before it is read) */
        std::vector<float, NoInit<float>> dbuf(rows * size_t(w) * disk.size());
        std::vector<float, NoInit<float>> cbuf(clamp01 ? rows * size_t(w) * size_t(nch) : 0);
        std::vector<ewio::BandSrc> bands(static_cast<size_t>(nch));
        std::vector<BandDst> dplanes(disk.size());
        std::vector<const float *> from(size_t(nch), nullptr);
        for (size_t k = 0; k < disk.size(); k++) {
            dplanes[k] = BandDst{dbuf.data() + k * rows * size_t(w), 1, size_t(w)};
            from[size_t(disk[k])] = dplanes[k].p;
        }
        for (int y0 = 0; y0 < h; y0 += int(rows)) {
            const int y1 = std::min(h, y0 + int(rows));
            const size_t b = size_t(y0) * size_t(w);
            const size_t n = size_t(y1 - y0) * size_t(w);
            if (!disk.empty() && !disk_in.read(y0, y1, dplanes.data(), msg)) {
                msg = what + msg;
                return 1;
            }
            for (int c = 0; c < nch; c++) {
                size_t ss = 1;
                const float *s = from[size_t(c)];
                if (!s) {
                    s = memory_pixels(f.ch[size_t(src[size_t(c)])], &ss);
                    s += b * ss;
                }
                if (clamp01) {
                    float *d = cbuf.data() + size_t(c) * rows * size_t(w);
                    for (size_t i = 0; i < n; i++) {
                        const float v = s[i * ss];
                        d[i] = std::isnan(v) ? 0.0f : v < 0.0f ? 0.0f : v > 1.0f ? 1.0f : v;
                    }
                    s = d;
                    ss = 1;
                }
                bands[size_t(c)] = ewio::BandSrc{s, ss, size_t(w) * ss};
            }
            std::string why;
            if (!out->write(y0, y1, bands.data(), why)) {
                msg = what + why;
                return 1;
            }
        }
    }
    {
        std::string why;
        const bool closed = out->close(why);
        out.reset();
        if (!closed) {
            msg = what + why;
            return 1;
        }
    }

    /* Check the file before it may replace anything: some writers report
     * short writes late or not at all (buffered output, PNG; OpenEXR's chunk
     * table, written on close). An EXR's chunks are checked in place, the
     * other formats decoded whole. */
    {
        std::string verr;
        if (!(kind == Kind::EXR ? written_exr_ok(guard.path, w, h, nch, verr)
                                : codec->read_back(guard.path, w, h, nch, verr))) {
            msg = what + "the written file does not read back (" + verr + ")";
            return 1;
        }
    }

    /* Make the data durable before it replaces the destination. */
    {
        int fd = open(guard.path.c_str(), O_RDONLY | O_CLOEXEC);
        if (fd < 0 || fsync(fd) != 0) {
            int e = errno;
            if (fd >= 0) close(fd);
            msg = what + "flushing the temporary file failed (" + errno_text(e) + ")";
            return 1;
        }
        struct stat tst;
        const bool empty = fstat(fd, &tst) != 0 || tst.st_size == 0;
        close(fd);
        if (empty) {
            msg = what + "the written file is empty";
            return 1;
        }
    }
    if (rename(guard.path.c_str(), path.c_str()) != 0) {
        msg = what + "rename of the temporary file failed (" + errno_text(errno) + ")";
        return 1;
    }
    guard.release();
    {
        int dfd = open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (dfd >= 0) {
            (void)fsync(dfd);
            close(dfd);
        }
    }
    return 0;
}

/* The text twin of write_impl's file handling: a temporary beside the
 * destination, every byte written and flushed, then renamed over it. */
int write_text_impl(const char *cpath, const char *text, size_t len, std::string &msg) {
    const std::string path(cpath);
    const std::string base = base_of(path);
    const std::string dir = dir_of(path);
    const std::string what = "cannot write " + q(path) + ": ";
    if (base.empty() || base == "." || base == "..") {
        msg = what + "not a file name";
        return 1;
    }
    struct stat dst_st;
    const bool dst_exists = stat(path.c_str(), &dst_st) == 0;
    if (dst_exists && S_ISDIR(dst_st.st_mode)) {
        msg = what + "is a directory";
        return 1;
    }
    if (dst_exists && !S_ISREG(dst_st.st_mode)) {
        msg = what + "not a regular file";
        return 1;
    }
    struct stat dir_st;
    if (stat(dir.c_str(), &dir_st) != 0 || !S_ISDIR(dir_st.st_mode)) {
        msg = what + "directory " + q(dir) + " does not exist";
        return 1;
    }
    TempGuard guard;
    const int fd = make_temp(guard, dir, base, lower_ext(base), dst_exists ? int(dst_st.st_mode & 07777) : -1);
    int e = errno;
    if (fd < 0) {
        msg = what + "cannot create a temporary file in " + q(dir) + " (" + errno_text(e) + ")";
        return 1;
    }
    size_t done = 0;
    while (done < len) {
        ssize_t k = ::write(fd, text + done, len - done);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) {
            e = k < 0 ? errno : ENOSPC;
            close(fd);
            msg = what + errno_text(e);
            return 1;
        }
        done += size_t(k);
    }
    if (fsync(fd) != 0) {
        e = errno;
        close(fd);
        msg = what + "flushing the temporary file failed (" + errno_text(e) + ")";
        return 1;
    }
    if (close(fd) != 0) {
        msg = what + errno_text(errno);
        return 1;
    }
    if (rename(guard.path.c_str(), path.c_str()) != 0) {
        msg = what + "rename of the temporary file failed (" + errno_text(errno) + ")";
        return 1;
    }
    guard.release();
    int dfd = open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {
        (void)fsync(dfd);
        close(dfd);
    }
    return 0;
}

} // namespace

/* ------------------------------------------------------------- threads */

namespace {
/* ewio_set_threads' count (0: not set, the machine's): the OpenImageIO
 * module takes it when it is loaded later. */
std::atomic<int> g_io_threads{0};

int machine_threads() {
    const unsigned n = std::thread::hardware_concurrency();
    return n > 0 ? int(std::min(n, 256u)) : 1;
}
} // namespace

int ewio::io_threads() {
    const int t = g_io_threads.load();
    return t > 0 ? t : machine_threads();
}

/* ------------------------------------- helpers of the C API below (C++ linkage) */

namespace {
/* Where a new channel of pass P goes: after the pass's last channel, else
 * the layer's, else at the end. */
size_t new_channel_pos(const ewio_file &f, const std::string &L, const std::string &P) {
    size_t pos = f.ch.size();
    int last_pass = -1, last_layer = -1;
    for (size_t j = 0; j < f.ch.size(); j++) {
        if (f.ch[j].layer != L) continue;
        last_layer = int(j);
        if (f.ch[j].pass == P) last_pass = int(j);
    }
    if (last_pass >= 0)
        pos = size_t(last_pass) + 1;
    else if (last_layer >= 0)
        pos = size_t(last_layer) + 1;
    return pos;
}

/* "" when (L, P, C) names channels that read back as that layer, pass and
 * those components; else why not (ewio_set_pass's rules). */
std::string pass_names_problem(const std::string &L, const std::string &P, const std::string &C, const char *fn) {
    if (!L.empty() && P.empty())
        return std::string(fn) + ": a pass name is required for layer " + q(L) + " (\"" + L + ".R\" would read back as pass " +
               q(L) + ")";
    for (size_t i = 0; i < C.size(); i++) {
        std::string l2, p2, c2;
        const std::string name = join_name(L, P, std::string(1, C[i]));
        split_name(name, l2, p2, c2);
        if (C.find(C[i]) != i || l2 != L || p2 != P || c2 != std::string(1, C[i]))
            return std::string(fn) + ": " + display_pass(L, P) + " components " + q(C) + ": channel name " + q(name) +
                   " is ambiguous (dots in the pass name or component, or a repeated component)";
    }
    return "";
}
} // namespace

namespace {
/* ewio_set_pass (a copy of src) and ewio_lend_pass (src itself). */
int put_pass(ewio_file *f, const char *layer, const char *pass, const char *comps, const float *src, bool lend,
             const char *fn, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!f || !comps || !*comps || !src) {
        set_err(err, errlen, std::string(fn) + ": invalid argument (NULL file/src or empty comps)");
        return 1;
    }
    try {
        const std::string L = layer ? layer : "", P = pass ? pass : "", C = comps;
        const std::string why = pass_names_problem(L, P, C, fn);
        if (!why.empty()) {
            set_err(err, errlen, why);
            return 1;
        }
        const size_t n = C.size(), npix = size_t(f->width) * size_t(f->height);
        /* Prepare everything that allocates before changing the file: planes
         * for new channels and for released ones; a channel that has its
         * pixels is overwritten where it is (no second copy of the pass). */
        std::vector<Plane> data(n);
        size_t nnew = 0;
        for (size_t k = 0; k < n; k++) {
            const int i = find_channel(*f, L, P, std::string(1, C[k]));
            if (i < 0) nnew++;
            if (!lend && (i < 0 || f->ch[size_t(i)].px.size() != npix)) data[k].resize(npix);
        }
        std::vector<Channel> fresh;
        fresh.reserve(nnew);
        for (size_t k = 0; k < n; k++) {
            if (find_channel(*f, L, P, std::string(1, C[k])) >= 0) continue;
            Channel c;
            c.layer = L;
            c.pass = P;
            c.comp = std::string(1, C[k]);
            c.name = join_name(L, P, c.comp);
            c.type = PixType::HALF;
            fresh.push_back(std::move(c));
        }
        f->ch.reserve(f->ch.size() + nnew);
        std::vector<std::string> layers = f->layers;
        if (!has_layer(*f, L)) layers.push_back(L);
        /* Commit: nothing below allocates. */
        size_t fi = 0;
        for (size_t k = 0; k < n; k++) {
            int i = find_channel(*f, L, P, std::string(1, C[k]));
            Channel *c;
            if (i >= 0) {
                c = &f->ch[size_t(i)];
            } else {
                const size_t pos = new_channel_pos(*f, L, P);
                f->ch.insert(f->ch.begin() + std::ptrdiff_t(pos), std::move(fresh[fi++]));
                c = &f->ch[pos];
            }
            c->on_disk = false;
            if (lend) {
                Plane().swap(c->px);
                c->lent = src + k;
                c->lent_stride = n;
                continue;
            }
            if (!data[k].empty()) c->px.swap(data[k]);
            unlend(*c);
            float *dst = c->px.data();
            for (size_t j = 0; j < npix; j++) dst[j] = src[j * n + k];
        }
        f->layers.swap(layers);
        return 0;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, std::string(fn) + ": out of memory");
    } catch (...) {
        set_err(err, errlen, std::string(fn) + ": unexpected error");
    }
    return 1;
}
} // namespace

/* ================================================================ C API */

extern "C" {

int ewio_write_text(const char *path, const char *text, size_t len, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!path || !*path || (!text && len)) {
        set_err(err, errlen, "ewio_write_text: invalid argument (NULL or empty path, or NULL text)");
        return 1;
    }
    try {
        std::string msg;
        int rc = write_text_impl(path, text ? text : "", len, msg);
        if (rc) set_err(err, errlen, msg);
        return rc;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, std::string("cannot write '") + path + "': out of memory");
    } catch (...) {
        set_err(err, errlen, std::string("cannot write '") + path + "': unexpected error");
    }
    return 1;
}

void ewio_remove_temporaries(void) {
    for (int i = 0; i < kTempSlots; i++)
        if (g_temps[i].state.load() == 2) unlink(g_temps[i].path);
}

void ewio_set_threads(int n) {
    try {
        const int t = n > 0 ? n : machine_threads();
        g_io_threads.store(t);
        ewio::exr_codec().set_threads(t);
        if (const Codec *c = ewio::oiio_codec_loaded()) c->set_threads(t);
    } catch (...) {
    }
}

int ewio_parse_size(const char *text, unsigned long long *out) {
    if (!text || !out) return 1;
    errno = 0;
    char *end = nullptr;
    const double v = strtod(text, &end);
    if (end == text || errno || !(v > 0) || !std::isfinite(v)) return 1;
    double mul = 1;
    std::string suf(end);
    for (char &c : suf) c = char(toupper((unsigned char)c));
    if (suf == "" || suf == "B") mul = 1;
    else if (suf == "K" || suf == "KB" || suf == "KIB") mul = 1024.0;
    else if (suf == "M" || suf == "MB" || suf == "MIB") mul = 1024.0 * 1024;
    else if (suf == "G" || suf == "GB" || suf == "GIB") mul = 1024.0 * 1024 * 1024;
    else if (suf == "T" || suf == "TB" || suf == "TIB") mul = 1024.0 * 1024 * 1024 * 1024;
    else return 1;
    const double b = v * mul;
    if (b < 1 || b > 1.8e19) return 1;
    *out = (unsigned long long)b;
    return 0;
}

unsigned long long ewio_max_memory(void) {
    unsigned long long v = 0;
    const char *e = getenv("EDGEWISE_MAX_MEMORY");
    if (e && *e && ewio_parse_size(e, &v) == 0) return v;
    return physical_memory() / 4 * 3;
}

long long ewio_max_pixels(void) {
    const char *e = getenv("EDGEWISE_MAX_PIXELS");
    if (e && *e) {
        char *end = nullptr;
        errno = 0;
        long long v = strtoll(e, &end, 10);
        if (end != e && *end == '\0' && errno == 0 && v >= 1) return std::min(v, kMaxPixels);
    }
    return kMaxPixels;
}

/* ewio_read and ewio_open: the same checks and error text around read_impl,
 * which decodes every pass now or (defer) only the headers. */
static int read_entry(const char *fn, const char *path, ewio_file **out, bool defer, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (out) *out = nullptr;
    if (!path || !*path || !out) {
        set_err(err, errlen, std::string(fn) + ": invalid argument (NULL or empty path, or NULL out)");
        return 1;
    }
    try {
        std::string msg;
        int rc = read_impl(path, out, msg, nullptr, defer);
        if (rc) set_err(err, errlen, msg);
        return rc;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, std::string("cannot read '") + path + "': out of memory");
    } catch (const std::exception &e) {
        set_err(err, errlen, std::string("cannot read '") + path + "': " + one_line(e.what()));
    } catch (...) {
        set_err(err, errlen, std::string("cannot read '") + path + "': unknown error");
    }
    return 1;
}

int ewio_read(const char *path, ewio_file **out, char *err, size_t errlen) {
    return read_entry("ewio_read", path, out, false, err, errlen);
}

int ewio_open(const char *path, ewio_file **out, char *err, size_t errlen) {
    return read_entry("ewio_open", path, out, true, err, errlen);
}

int ewio_load_passes(ewio_file *f, const ewio_pass_ref *refs, int n, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!f || (n > 0 && !refs) || n < 0) {
        set_err(err, errlen, "ewio_load_passes: invalid argument");
        return 1;
    }
    try {
        const size_t npix = size_t(f->width) * size_t(f->height), w = size_t(f->width);
        /* What one pass over the file decodes: chans[k] into at[k] (its
         * value at pixel (0, 0) and its strides) — a ref's dst, or a plane
         * the file keeps (keep: the k that are) */
        std::vector<int> chans, keep, late;
        std::vector<BandDst> at;
        for (int r = 0; r < n; r++) {
            const std::string L = refs[r].layer ? refs[r].layer : "", P = refs[r].pass ? refs[r].pass : "";
            if (refs[r].dst) {
                if (!refs[r].comps || !*refs[r].comps) {
                    set_err(err, errlen, "ewio_load_passes: a pass decoded into dst needs its comps");
                    return 1;
                }
                const std::string C = refs[r].comps;
                std::vector<int> idx;
                const std::string missing = pass_channels(*f, L, P, C, idx);
                if (!missing.empty()) {
                    set_err(err, errlen, missing);
                    return 1;
                }
                bool on_disk = true;
                for (int i : idx) on_disk = on_disk && f->ch[size_t(i)].on_disk;
                if (!on_disk) { /* in memory (not a scanline EXR, or set since): copied below */
                    late.push_back(r);
                    continue;
                }
                for (size_t k = 0; k < C.size(); k++) {
                    chans.push_back(idx[k]);
                    at.push_back(BandDst{refs[r].dst + k, C.size(), w * C.size()});
                }
                continue;
            }
            for (size_t i = 0; i < f->ch.size(); i++) {
                const Channel &c = f->ch[i];
                if (!c.on_disk || c.layer != L || c.pass != P) continue;
                if (refs[r].comps && !std::strstr(refs[r].comps, c.comp.c_str())) continue;
                if (refs[r].comps && c.comp.size() != 1) continue;
                bool kept = false;
                for (int k : keep) kept = kept || chans[size_t(k)] == int(i);
                if (kept) continue;
                keep.push_back(int(chans.size()));
                chans.push_back(int(i));
                at.push_back(BandDst{nullptr, 1, w});
            }
        }
        std::vector<Plane> px(keep.size());
        for (size_t j = 0; j < keep.size(); j++) {
            px[j].resize(npix);
            at[size_t(keep[j])].p = px[j].data();
        }
        if (!chans.empty()) {
            SourceReader rd;
            std::string why;
            if (!rd.open(*f, chans, why) || !rd.read_all(at, why)) {
                set_err(err, errlen, why);
                return 1;
            }
        }
        for (int r : late)
            if (ewio_get_pass(f, refs[r].layer, refs[r].pass, refs[r].comps, refs[r].dst, err, errlen) != 0) return 1;
        for (size_t j = 0; j < keep.size(); j++) {
            Channel &c = f->ch[size_t(chans[size_t(keep[j])])];
            c.px.swap(px[j]);
            c.on_disk = false;
        }
        return 0;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, "ewio_load_passes: out of memory");
    } catch (...) {
        set_err(err, errlen, "ewio_load_passes: unexpected error");
    }
    return 1;
}

int ewio_read_header(const char *path, ewio_header *out, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!path || !*path || !out) {
        set_err(err, errlen, "ewio_read_header: invalid argument (NULL or empty path, or NULL out)");
        return 1;
    }
    memset(out, 0, sizeof *out);
    try {
        std::string msg;
        int rc = read_impl(path, nullptr, msg, out);
        if (rc) set_err(err, errlen, msg);
        return rc;
    } catch (const std::exception &e) {
        set_err(err, errlen, std::string("cannot read '") + path + "': " + one_line(e.what()));
    } catch (...) {
        set_err(err, errlen, std::string("cannot read '") + path + "': unknown error");
    }
    return 1;
}

void ewio_free(ewio_file *f) { delete f; }

int ewio_width(const ewio_file *f) { return f ? f->width : 0; }
int ewio_height(const ewio_file *f) { return f ? f->height : 0; }
int ewio_num_channels(const ewio_file *f) { return f ? int(f->ch.size()) : 0; }

const char *ewio_channel_name(const ewio_file *f, int i) {
    if (!f || i < 0 || size_t(i) >= f->ch.size()) return nullptr;
    return f->ch[size_t(i)].name.c_str();
}

int ewio_num_layers(const ewio_file *f) { return f ? int(f->layers.size()) : 0; }

const char *ewio_layer_name(const ewio_file *f, int i) {
    if (!f || i < 0 || size_t(i) >= f->layers.size()) return nullptr;
    return f->layers[size_t(i)].c_str();
}

int ewio_get_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps,
                  float *dst, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!f || !comps || !*comps || !dst) {
        set_err(err, errlen, "ewio_get_pass: invalid argument (NULL file/dst or empty comps)");
        return 1;
    }
    try {
        const std::string L = layer ? layer : "", P = pass ? pass : "", C = comps;
        std::vector<int> idx;
        const std::string missing = pass_channels(*f, L, P, C, idx);
        if (!missing.empty()) {
            set_err(err, errlen, missing);
            return 1;
        }
        const size_t n = C.size(), npix = size_t(f->width) * size_t(f->height);
        std::vector<int> disk;
        for (size_t k = 0; k < n; k++) {
            const Channel &c = f->ch[size_t(idx[k])];
            if (c.on_disk) disk.push_back(int(k));
            else if (!in_memory(c, npix)) {
                set_err(err, errlen, "ewio_get_pass: the pixels of " + display_pass(L, P) +
                                         " were released (ewio_release_pass) and not set again");
                return 1;
            }
        }
        /* the channels on disk are decoded straight into dst, band by band */
        if (!disk.empty()) {
            std::vector<int> chans;
            std::vector<BandDst> at;
            for (int k : disk) {
                chans.push_back(idx[size_t(k)]);
                at.push_back(BandDst{dst + size_t(k), n, size_t(f->width) * n});
            }
            SourceReader rd;
            std::string why;
            if (!rd.open(*f, chans, why) || !rd.read_all(at, why)) {
                set_err(err, errlen, why);
                return 1;
            }
        }
        size_t j = 0;
        for (size_t k = 0; k < n; k++) {
            if (j < disk.size() && disk[j] == int(k)) {
                j++;
                continue;
            }
            size_t ss = 1;
            const float *s = memory_pixels(f->ch[size_t(idx[k])], &ss);
            float *d = dst + k;
            for (size_t i = 0; i < npix; i++) d[i * n] = s[i * ss];
        }
        return 0;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, "ewio_get_pass: out of memory");
    } catch (...) {
        set_err(err, errlen, "ewio_get_pass: unexpected error");
    }
    return 1;
}

int ewio_release_pass(ewio_file *f, const char *layer, const char *pass, const char *comps) {
    if (!f || !comps || !*comps) return 1;
    try {
        const std::string L = layer ? layer : "", P = pass ? pass : "";
        std::vector<int> idx;
        for (const char *c = comps; *c; c++) {
            const int i = find_channel(*f, L, P, std::string(1, *c));
            if (i < 0) return 1;
            idx.push_back(i);
        }
        for (int i : idx) {
            Plane().swap(f->ch[size_t(i)].px);
            unlend(f->ch[size_t(i)]);
            f->ch[size_t(i)].on_disk = false;
        }
        return 0;
    } catch (...) {
        return 1;
    }
}

int ewio_has_pass(const ewio_file *f, const char *layer, const char *pass, const char *comps) {
    if (!f || !comps || !*comps) return 0;
    try {
        const std::string L = layer ? layer : "", P = pass ? pass : "";
        for (const char *c = comps; *c; c++)
            if (find_channel(*f, L, P, std::string(1, *c)) < 0) return 0;
        return 1;
    } catch (...) {
        return 0;
    }
}


int ewio_pass_in_source(const ewio_file *f, const char *layer, const char *pass, const char *comps) {
    return every_channel(f, layer, pass, comps, [](const Channel &c) { return c.in_src; });
}

int ewio_pass_stored_half(const ewio_file *f, const char *layer, const char *pass, const char *comps) {
    return every_channel(f, layer, pass, comps, [](const Channel &c) { return c.type == PixType::HALF; });
}

void ewio_floats_to_half(const float *src, uint16_t *dst, size_t n) { ewio::to_half(src, dst, n); }

int ewio_set_pass_from_source(ewio_file *f, const char *layer, const char *pass, const char *comps,
                              const char *from_pass, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!f || !comps || !*comps) {
        set_err(err, errlen, "ewio_set_pass_from_source: invalid argument (NULL file or empty comps)");
        return 1;
    }
    try {
        const std::string L = layer ? layer : "", P = pass ? pass : "", C = comps, F = from_pass ? from_pass : "";
        std::string why = pass_names_problem(L, P, C, "ewio_set_pass_from_source");
        if (!why.empty()) {
            set_err(err, errlen, why);
            return 1;
        }
        std::vector<int> from;
        for (char c : C) {
            const int i = find_channel(*f, L, F, std::string(1, c));
            if (i < 0 || !f->ch[size_t(i)].in_src) {
                set_err(err, errlen, "ewio_set_pass_from_source: " + display_pass(L, F) + " component " +
                                         q(std::string(1, c)) + " is not in the file it was read from");
                return 1;
            }
            from.push_back(i);
        }
        /* the source channels' places, before any insertion moves them */
        std::vector<std::pair<int, int>> refs;
        for (int i : from) refs.push_back({f->ch[size_t(i)].part, f->ch[size_t(i)].part_ch});
        std::vector<std::string> layers = f->layers;
        if (!has_layer(*f, L)) layers.push_back(L);
        f->ch.reserve(f->ch.size() + C.size());
        for (size_t k = 0; k < C.size(); k++) {
            int i = find_channel(*f, L, P, std::string(1, C[k]));
            if (i < 0) {
                Channel c;
                c.layer = L;
                c.pass = P;
                c.comp = std::string(1, C[k]);
                c.name = join_name(L, P, c.comp);
                c.type = PixType::HALF; /* as ewio_set_pass's new channels */
                const size_t pos = new_channel_pos(*f, L, P);
                f->ch.insert(f->ch.begin() + std::ptrdiff_t(pos), std::move(c));
                i = int(pos);
            }
            Channel &c = f->ch[size_t(i)];
            Plane().swap(c.px);
            unlend(c);
            c.on_disk = true;
            c.in_src = true;
            c.part = refs[k].first;
            c.part_ch = refs[k].second;
        }
        f->layers.swap(layers);
        return 0;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, "ewio_set_pass_from_source: out of memory");
    } catch (...) {
        set_err(err, errlen, "ewio_set_pass_from_source: unexpected error");
    }
    return 1;
}


int ewio_set_pass(ewio_file *f, const char *layer, const char *pass, const char *comps, const float *src, char *err,
                  size_t errlen) {
    return put_pass(f, layer, pass, comps, src, false, "ewio_set_pass", err, errlen);
}

int ewio_lend_pass(ewio_file *f, const char *layer, const char *pass, const char *comps, const float *src, char *err,
                   size_t errlen) {
    return put_pass(f, layer, pass, comps, src, true, "ewio_lend_pass", err, errlen);
}

const char *ewio_get_attribute(const ewio_file *f, const char *name) {
    if (!f || !name) return "";
    try {
        auto it = f->attr_text.find(name);
        return it == f->attr_text.end() ? "" : it->second.c_str();
    } catch (...) {
        return "";
    }
}

int ewio_set_attribute(ewio_file *f, const char *name, const char *value) {
    if (!f || !name || !*name) return 1;
    try {
        const std::string n = name;
        if (!value) {
            f->attribs.erase(std::remove_if(f->attribs.begin(), f->attribs.end(),
                                            [&](const Attr &a) { return a.name == n; }),
                             f->attribs.end());
            f->attr_text.erase(n);
            if (n == "compression") f->exr_compression.clear();
            return 0;
        }
        const std::string v = value;
        if (n == "compression") { /* the EXR's compression, not a header attribute of its own */
            f->exr_compression = v;
            f->attr_text[n] = v;
            return 0;
        }
        Attr *old = find_attr(*f, n);
        Attr now = ewio::attr_string(n, v);
        if (old && old->type == "int" && !v.empty()) {
            char *end = nullptr;
            errno = 0;
            long x = strtol(v.c_str(), &end, 10);
            if (*end == '\0' && errno == 0 && x >= INT32_MIN && x <= INT32_MAX) now = ewio::attr_int(n, int32_t(x));
        } else if (old && old->type == "float" && !v.empty()) {
            char *end = nullptr;
            float x = strtof(v.c_str(), &end);
            if (*end == '\0') now = ewio::attr_float(n, x);
        }
        if (old)
            *old = now;
        else
            f->attribs.push_back(now);
        f->attr_text[n] = ewio::attr_text(now);
        return 0;
    } catch (...) {
        return 1;
    }
}

int ewio_write(const ewio_file *f, const char *path, ewio_pixel_type type, const char *layer,
               const char *pass, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (!f || !path || !*path) {
        set_err(err, errlen, "ewio_write: invalid argument (NULL file or empty path)");
        return 1;
    }
    try {
        std::string msg;
        int rc = write_impl(*f, path, type, layer, pass, msg);
        if (rc) set_err(err, errlen, msg);
        return rc;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, std::string("cannot write '") + path + "': out of memory");
    } catch (const std::exception &e) {
        set_err(err, errlen, std::string("cannot write '") + path + "': " + one_line(e.what()));
    } catch (...) {
        set_err(err, errlen, std::string("cannot write '") + path + "': unknown error");
    }
    return 1;
}

int ewio_create(int width, int height, ewio_file **out, char *err, size_t errlen) {
    clear_err(err, errlen);
    if (out) *out = nullptr;
    if (!out) {
        set_err(err, errlen, "ewio_create: invalid argument (NULL out)");
        return 1;
    }
    try {
        std::string d = check_dims(width, height);
        if (!d.empty()) {
            set_err(err, errlen, "ewio_create: " + d);
            return 1;
        }
        ewio_file *f = new ewio_file;
        f->width = f->full_width = width;
        f->height = f->full_height = height;
        *out = f;
        return 0;
    } catch (const std::bad_alloc &) {
        set_err(err, errlen, "ewio_create: out of memory");
    } catch (...) {
        set_err(err, errlen, "ewio_create: unexpected error");
    }
    return 1;
}

int ewio_pass_read_as_integer(const ewio_file *f, const char *layer, const char *pass) {
    if (!f) return 0;
    const std::string l = layer ? layer : "", p = pass ? pass : "";
    bool any = false;
    for (const Channel &c : f->ch)
        if (c.layer == l && c.pass == p) {
            any = true;
            if (c.type != PixType::U8 && c.type != PixType::U16) return 0;
        }
    return any ? 1 : 0;
}

int ewio_write_is_integer(const ewio_file *f, const char *path, ewio_pixel_type type, const char *layer,
                          const char *pass) {
    if (!f || !path) return -1;
    const std::string ext = lower_ext(base_of(path));
    if (ext == "png" || ext == "jpg" || ext == "jpeg") return 1;
    if (ext == "exr") return 0;
    if (ext != "tif" && ext != "tiff") return -1;
    /* TIFF keeps 8/16-bit only for a pass read as such (write_impl) */
    return type == EWIO_KEEP && ewio_pass_read_as_integer(f, layer, pass) ? 1 : 0;
}


} // extern "C"
