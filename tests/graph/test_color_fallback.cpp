// test_color_fallback.cpp — the OpenColorIO shim's built-in fallback config
// (what a machine without $OCIO and without Blender gets on OCIO 2.1): the
// shim compiled without its Blender search, $OCIO unset.
#define EW_COLOR_TEST_NO_BLENDER 1
#include "ewcolor.cpp"

#include <cstdio>
#include <cstdlib>
#include <cstring>

static int failed = 0, passed = 0;
#define EXPECT(cond)                                                            \
    do {                                                                        \
        if (cond) passed++;                                                     \
        else {                                                                  \
            failed++;                                                           \
            std::fprintf(stderr, "FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                       \
    } while (0)

int main() {
    unsetenv("OCIO");
    char name[512], err[1024];
    ewcolor_config_name(name, sizeof name);
    std::printf("config: %s\n", name);
#if OCIO_VERSION_HEX < 0x02020000
    EXPECT(std::strstr(name, "built-in fallback") != nullptr);
#endif
    ewcolor_proc *p = nullptr;
    // the sRGB curve at 18 % grey, through both nodes' paths
    EXPECT(ewcolor_transform("scene_linear", "sRGB", &p, err, sizeof err) == 0);
    float px[3] = {0.18f, 0.0f, 1.0f};
    ewcolor_apply(p, px, 1, 1, 3);
    EXPECT(std::fabs(px[0] - 0.46135f) < 1e-3f && std::fabs(px[1]) < 1e-6f && std::fabs(px[2] - 1.0f) < 1e-4f);
    ewcolor_free(p);
    EXPECT(ewcolor_display("", "", "", "", 0.0f, 1.0f, &p, err, sizeof err) == 0);
    // RGBA is associated: the colour 0.09 at alpha 0.5 is 0.18 shown at half coverage
    float q[4] = {0.09f, 0.09f, 0.09f, 0.5f};
    ewcolor_apply(p, q, 1, 1, 4);
    EXPECT(std::fabs(q[0] - 0.5f * 0.46135f) < 1e-3f && q[3] == 0.5f);
    ewcolor_free(p);
    EXPECT(ewcolor_display("", "sRGB", "Raw", "", 1.0f, 1.0f, &p, err, sizeof err) == 0);
    float r[3] = {0.25f, 0.25f, 0.25f};
    ewcolor_apply(p, r, 1, 1, 3);
    EXPECT(std::fabs(r[0] - 0.5f) < 1e-6f); // one stop of exposure, raw view
    ewcolor_free(p);
    EXPECT(ewcolor_display("", "sRGB", "Filmic", "", 0.0f, 1.0f, &p, err, sizeof err) != 0);
    EXPECT(std::strstr(err, "unknown view 'Filmic'") && std::strstr(err, "views: Standard, Raw"));
    EXPECT(ewcolor_transform("Linear", "ACEScg", &p, err, sizeof err) != 0);
    EXPECT(std::strstr(err, "unknown colour space 'ACEScg'") != nullptr);
    std::printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
