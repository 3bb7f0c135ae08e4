// ewcolor.cpp — OpenColorIO behind a C interface (see ewcolor.h).
#include "ewcolor.h"

#include <OpenColorIO/OpenColorIO.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <sys/stat.h>

namespace OCIO = OCIO_NAMESPACE;

struct ewcolor_proc {
    OCIO::ConstCPUProcessorRcPtr cpu;
    float exposure_scale = 1.0f; // applied before the processor
    float inv_gamma = 1.0f;      // applied after it
};

namespace {

// Debian's blender-data installs here; the versioned path is what upstream
// Blender builds use.
[[maybe_unused]] const char *const blender_configs[] = {
    "/usr/share/blender/datafiles/colormanagement/config.ocio",
    "/usr/share/blender/3.4/datafiles/colormanagement/config.ocio",
    nullptr,
};

[[maybe_unused]] bool file_exists(const char *p) {
    struct stat st;
    return stat(p, &st) == 0 && S_ISREG(st.st_mode);
}

// The last resort: scene linear, raw data and sRGB with the standard
// piecewise curve (gamma 2.4, offset 0.055), one display.
OCIO::ConstConfigRcPtr fallback_config() {
    OCIO::ConfigRcPtr cfg = OCIO::Config::Create();
    cfg->setMajorVersion(2);
    auto lin = OCIO::ColorSpace::Create();
    lin->setName("Linear");
    lin->setFamily("linear");
    cfg->addColorSpace(lin);
    auto raw = OCIO::ColorSpace::Create();
    raw->setName("Raw");
    raw->setIsData(true);
    cfg->addColorSpace(raw);
    auto srgb = OCIO::ColorSpace::Create();
    srgb->setName("sRGB");
    auto curve = OCIO::ExponentWithLinearTransform::Create();
    const double g[4] = {2.4, 2.4, 2.4, 1.0}, o[4] = {0.055, 0.055, 0.055, 0.0};
    curve->setGamma(g);
    curve->setOffset(o);
    srgb->setTransform(curve, OCIO::COLORSPACE_DIR_TO_REFERENCE);
    cfg->addColorSpace(srgb);
    cfg->setRole(OCIO::ROLE_SCENE_LINEAR, "Linear");
    cfg->setRole(OCIO::ROLE_REFERENCE, "Linear");
    cfg->setRole(OCIO::ROLE_DEFAULT, "Linear");
    cfg->setRole(OCIO::ROLE_DATA, "Raw");
    cfg->setRole(OCIO::ROLE_COLOR_PICKING, "sRGB");
    cfg->addDisplayView("sRGB", "Standard", "sRGB", "");
    cfg->addDisplayView("sRGB", "Raw", "Raw", "");
    cfg->validate();
    return cfg;
}

OCIO::ConstConfigRcPtr load_config(std::string *which) {
    const char *env = std::getenv("OCIO");
    if (env && *env) {
        *which = std::string("$OCIO=") + env;
        return OCIO::Config::CreateFromFile(env);
    }
    // tests/graph/test_color_fallback.cpp compiles this file without the
    // Blender search to test the fallback on a machine that has Blender.
#ifndef EW_COLOR_TEST_NO_BLENDER
    for (int i = 0; blender_configs[i]; i++)
        if (file_exists(blender_configs[i])) {
            *which = std::string("Blender: ") + blender_configs[i];
            return OCIO::Config::CreateFromFile(blender_configs[i]);
        }
#endif
#if OCIO_VERSION_HEX >= 0x02020000
    *which = "OpenColorIO built-in ocio://default";
    return OCIO::Config::CreateFromFile("ocio://default");
#else
    *which = "built-in fallback (Linear, Raw, sRGB; OpenColorIO " OCIO_VERSION " has no ocio://default)";
    return fallback_config();
#endif
}

void set_err(char *err, size_t len, const std::string &msg) {
    if (err && len) std::snprintf(err, len, "%s", msg.c_str());
}

std::string list_spaces(const OCIO::ConstConfigRcPtr &cfg) {
    std::string s;
    for (int i = 0; i < cfg->getNumColorSpaces() && s.size() < 400; i++) {
        if (i) s += ", ";
        s += cfg->getColorSpaceNameByIndex(i);
    }
    return s;
}

std::string list_displays(const OCIO::ConstConfigRcPtr &cfg) {
    std::string s;
    for (int i = 0; i < cfg->getNumDisplays(); i++) {
        if (i) s += ", ";
        s += cfg->getDisplay(i);
    }
    return s;
}

std::string list_views(const OCIO::ConstConfigRcPtr &cfg, const char *display) {
    std::string s;
    for (int i = 0; i < cfg->getNumViews(display); i++) {
        if (i) s += ", ";
        s += cfg->getView(display, i);
    }
    return s;
}

bool has_space(const OCIO::ConstConfigRcPtr &cfg, const char *name) {
    return cfg->getColorSpace(name) != nullptr; // names, aliases and roles
}

} // namespace

extern "C" void ewcolor_config_name(char *buf, size_t len) {
    std::string which;
    try {
        load_config(&which);
    } catch (const std::exception &e) {
        which += std::string(" (failed to load: ") + e.what() + ")";
    }
    if (buf && len) std::snprintf(buf, len, "%s", which.c_str());
}

extern "C" int ewcolor_transform(const char *from, const char *to, ewcolor_proc **out, char *err, size_t errlen) {
    *out = nullptr;
    std::string which;
    try {
        auto cfg = load_config(&which);
        if (!from || !*from) from = OCIO::ROLE_SCENE_LINEAR;
        if (!to || !*to) to = OCIO::ROLE_SCENE_LINEAR;
        for (const char *name : {from, to})
            if (!has_space(cfg, name)) {
                set_err(err, errlen, std::string("unknown colour space '") + name + "' in " + which +
                                         " (colour spaces: " + list_spaces(cfg) + ")");
                return 1;
            }
        auto proc = cfg->getProcessor(from, to);
        auto *p = new ewcolor_proc;
        p->cpu = proc->getDefaultCPUProcessor();
        *out = p;
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errlen, std::string("OpenColorIO (") + which + "): " + e.what());
        return 1;
    }
}

extern "C" int ewcolor_display(const char *from, const char *display, const char *view, const char *look,
                               float exposure, float gamma, ewcolor_proc **out, char *err, size_t errlen) {
    *out = nullptr;
    std::string which;
    try {
        auto cfg = load_config(&which);
        if (!from || !*from) from = OCIO::ROLE_SCENE_LINEAR;
        if (!has_space(cfg, from)) {
            set_err(err, errlen, std::string("unknown colour space '") + from + "' in " + which +
                                     " (colour spaces: " + list_spaces(cfg) + ")");
            return 1;
        }
        if (!display || !*display) display = cfg->getDefaultDisplay();
        bool found = false;
        for (int i = 0; i < cfg->getNumDisplays(); i++) found |= std::strcmp(cfg->getDisplay(i), display) == 0;
        if (!found) {
            set_err(err, errlen, std::string("unknown display '") + display + "' in " + which +
                                     " (displays: " + list_displays(cfg) + ")");
            return 1;
        }
        if (!view || !*view) view = cfg->getDefaultView(display);
        found = false;
        for (int i = 0; i < cfg->getNumViews(display); i++) found |= std::strcmp(cfg->getView(display, i), view) == 0;
        if (!found) {
            set_err(err, errlen, std::string("unknown view '") + view + "' for display '" + display + "' in " +
                                     which + " (views: " + list_views(cfg, display) + ")");
            return 1;
        }
        if (look && *look && !cfg->getLook(look)) {
            std::string looks;
            for (int i = 0; i < cfg->getNumLooks(); i++) looks += std::string(i ? ", " : "") + cfg->getLookNameByIndex(i);
            set_err(err, errlen, std::string("unknown look '") + look + "' in " + which + " (looks: " +
                                     (looks.empty() ? "none" : looks) + ")");
            return 1;
        }
        auto dvt = OCIO::DisplayViewTransform::Create();
        dvt->setSrc(from);
        dvt->setDisplay(display);
        dvt->setView(view);
        auto pipe = OCIO::LegacyViewingPipeline::Create();
        pipe->setDisplayViewTransform(dvt);
        if (look && *look) {
            pipe->setLooksOverrideEnabled(true);
            pipe->setLooksOverride(look);
        }
        auto proc = pipe->getProcessor(cfg);
        auto *p = new ewcolor_proc;
        p->cpu = proc->getDefaultCPUProcessor();
        p->exposure_scale = std::exp2(exposure);
        p->inv_gamma = gamma > 0.0f ? 1.0f / gamma : 1.0f;
        *out = p;
        return 0;
    } catch (const std::exception &e) {
        set_err(err, errlen, std::string("OpenColorIO (") + which + "): " + e.what());
        return 1;
    }
}

extern "C" void ewcolor_default_view(const char *display, char *display_out, size_t dlen, char *view_out,
                                     size_t vlen) {
    std::string which, d, v;
    try {
        auto cfg = load_config(&which);
        d = display && *display ? display : cfg->getDefaultDisplay();
        v = cfg->getDefaultView(d.c_str());
    } catch (const std::exception &) {
    }
    if (display_out && dlen) std::snprintf(display_out, dlen, "%s", d.c_str());
    if (view_out && vlen) std::snprintf(view_out, vlen, "%s", v.c_str());
}

extern "C" void ewcolor_apply(const ewcolor_proc *p, float *px, int width, int height, int channels) {
    if (!p || !px || width <= 0 || height <= 0 || (channels != 3 && channels != 4)) return;
    const size_t n = (size_t)width * (size_t)height;
    if (p->exposure_scale != 1.0f)
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) px[i * channels + c] *= p->exposure_scale;
    // RGBA is associated (premultiplied) as in EXR: a non-linear view
    // transform applies to the colour itself, so divide by alpha around it
    // (alpha 0 or 1, and non-finite alpha, leave the pixel as it is).
    auto partial = [](float a) { return a > 0.0f && a < 1.0f; };
    if (channels == 4)
        for (size_t i = 0; i < n; i++)
            if (partial(px[i * 4 + 3]))
                for (int c = 0; c < 3; c++) px[i * 4 + c] /= px[i * 4 + 3];
    try {
        OCIO::PackedImageDesc desc(px, width, height, channels);
        p->cpu->apply(desc);
    } catch (const std::exception &) {
        // A CPU processor built without error does not fail on valid packed
        // float memory; nothing sensible to report from here.
    }
    // Blender's display gamma: a power on display values, sign kept so
    // negative (out-of-gamut) values stay negative rather than NaN.
    if (p->inv_gamma != 1.0f)
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) {
                float v = px[i * channels + c];
                px[i * channels + c] = v < 0.0f ? -std::pow(-v, p->inv_gamma) : std::pow(v, p->inv_gamma);
            }
    if (channels == 4)
        for (size_t i = 0; i < n; i++)
            if (partial(px[i * 4 + 3]))
                for (int c = 0; c < 3; c++) px[i * 4 + c] *= px[i * 4 + 3];
}

extern "C" void ewcolor_free(ewcolor_proc *p) { delete p; }
