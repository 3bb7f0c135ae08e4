/*
 * node_io.c — nodes that move pixels in and out of a graph: read and write
 * image files (through ewio), and "input"/"output",
 * which exchange caller memory (the C API and Python's numpy arrays).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cycles_passes.h"
#include "ewio.h"
#include "graph.h"

/* ---- read ---------------------------------------------------------------- */

enum { R_COLOR, R_ALBEDO, R_NORMAL, R_DEPTH, R_Z, R_VECTOR, R_IMAGE, R_NOISY, R_NUM };

static const ew_port_desc read_outputs[] = {
    {"color", EW_PASS_COLOR, 3, 0, "colour RGB, the image the file shows: 'Combined' (a plain file: R,G,B)"},
    {"albedo", EW_PASS_ALBEDO, 3, 0, "'Denoising Albedo', else 'DiffCol'"},
    {"normal", EW_PASS_NORMAL, 3, 0, "'Denoising Normal', else 'Normal' (X,Y,Z)"},
    {"depth", EW_PASS_DEPTH, 1, 0, "'Denoising Depth', else 'Depth' (Z): guidance for denoisers"},
    {"z", EW_PASS_DEPTH, 1, 0, "'Depth' (Z): planar camera distance, what depth of field needs"},
    {"vector", EW_PASS_VECTOR, 4, 0, "'Vector' (X,Y,Z,W): motion vectors"},
    {"image", EW_PASS_ANY, 1, 0, "the pass named by 'pass', all its components in file order"},
    {"noisy", EW_PASS_COLOR, 3, 0,
     "a denoiser's input RGB: 'Noisy Image' when a denoiser already ran (Blender keeps the original there), else "
     "the colour"},
};

static const ew_nparam_desc read_params[] = {
    {"path", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 1, 1, "Path",
     "image file (EXR, multilayer EXR, PNG, TIFF); a run of '#' or a %04d is the frame number, e.g. "
     "render_####.exr"},
    {"layer", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Layer",
     "view layer, e.g. 'ViewLayer'; empty: the first layer with a colour pass"},
    {"pass", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Pass",
     "pass for the 'image' output, e.g. 'Emit' or 'Shadow Catcher'"},
};

typedef struct {
    ewio_file *file; /* the last file read, kept from validation for the first frame */
    int frame;
    char path[4096];
    char layer[256]; /* the layer read this frame (a write keeping the source writes into it) */
    /* a write downstream keeps the source file (keep_source): the frame's
     * file stays in memory after the read and that write takes it, instead
     * of reading and decoding the same file a second time */
    int keep_file;
} read_state;

static void read_release(ew_gnode *n) {
    read_state *s = (read_state *)n->state;
    if (s) ewio_free(s->file);
    free(s);
    n->state = NULL;
}

static read_state *read_state_get(ew_gnode *n) {
    if (!n->state) n->state = calloc(1, sizeof(read_state));
    return (read_state *)n->state;
}

/* Split a channel name as ewio does: component after the last '.', pass
 * before it, layer the rest. */
static void split_channel(const char *name, char *layer, char *pass, char *comp, size_t len) {
    const char *last = strrchr(name, '.');
    if (!last) {
        snprintf(layer, len, "%s", "");
        snprintf(pass, len, "%s", "");
        snprintf(comp, len, "%s", name);
        return;
    }
    snprintf(comp, len, "%s", last + 1);
    const char *prev = last;
    while (prev > name && prev[-1] != '.') prev--;
    snprintf(pass, len, "%.*s", (int)(last - prev), prev);
    if (prev > name) snprintf(layer, len, "%.*s", (int)(prev - 1 - name), name);
    else snprintf(layer, len, "%s", "");
}

/* Components of a pass in file order as one-letter names ("RGB", "Z"). */
static int pass_components(const ewio_file *f, const char *layer, const char *pass, char *comps, size_t len) {
    size_t k = 0;
    for (int i = 0; i < ewio_num_channels(f); i++) {
        char l[256], p[256], c[256];
        split_channel(ewio_channel_name(f, i), l, p, c, sizeof l);
        if (strcmp(l, layer) != 0 || strcmp(p, pass) != 0) continue;
        if (strlen(c) != 1) continue; /* ewio addresses components by one letter */
        if (k + 1 < len) comps[k++] = c[0];
    }
    comps[k] = '\0';
    return (int)k;
}

static void list_passes(const ewio_file *f, const char *layer, char *buf, size_t len) {
    size_t used = 0;
    buf[0] = '\0';
    char seen[2048] = "|";
    for (int i = 0; i < ewio_num_channels(f) && used < len; i++) {
        char l[256], p[256], c[256], key[300];
        split_channel(ewio_channel_name(f, i), l, p, c, sizeof l);
        if (strcmp(l, layer) != 0) continue;
        snprintf(key, sizeof key, "|%s|", p);
        if (strstr(seen, key)) continue;
        if (strlen(seen) + strlen(p) + 2 < sizeof seen) {
            strcat(seen, p);
            strcat(seen, "|");
        }
        int w = snprintf(buf + used, len - used, "%s'%s'", used ? ", " : "", p);
        if (w < 0) break;
        used += (size_t)w;
    }
    if (!used) snprintf(buf, len, "none");
}

static int wants_cycles_pass(const ew_gnode *n) {
    for (int o = R_COLOR; o <= R_DEPTH; o++)
        if (ew_node_output_wanted(n, o)) return 1;
    return ew_node_output_wanted(n, R_NOISY);
}

/* Which layer to read: the parameter, else the first with a colour pass
 * (for color/albedo/normal/depth), else the first layer. */
static int pick_layer(ew_gnode *n, const ewio_file *f, const char *path, char *layer, size_t len) {
    const char *want = ew_node_str(n, "layer");
    char layers[1024];
    ew_list_layers(f, layers, sizeof layers);
    if (want[0]) {
        for (int i = 0; i < ewio_num_layers(f); i++)
            if (!strcmp(ewio_layer_name(f, i), want)) {
                snprintf(layer, len, "%s", want);
                return 0;
            }
        ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'layer': no layer '%s' in '%s' (layers: %s)", want, path,
                     layers);
        return 1;
    }
    if (wants_cycles_pass(n)) {
        char err[512];
        ew_layer_passes lp;
        for (int i = 0; i < ewio_num_layers(f); i++)
            if (ew_find_image_passes(f, ewio_layer_name(f, i), &lp, err, sizeof err) == 0) {
                snprintf(layer, len, "%s", lp.layer);
                return 0;
            }
        ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "output 'color': '%s' has no layer with a colour pass (layers: %s)",
                     path, layers);
        return 1;
    }
    snprintf(layer, len, "%s", ewio_num_layers(f) ? ewio_layer_name(f, 0) : "");
    return 0;
}

/* Where each wanted output comes from, or an error naming the missing pass. */
typedef struct {
    const char *pass[R_NUM];
    char comps[R_NUM][8];
} read_map;

static ew_result map_passes(ew_gnode *n, const ewio_file *f, const char *path, const char *layer, read_map *m) {
    memset(m, 0, sizeof *m);
    char passes[1024], err[512];
    ew_layer_passes lp, noisy;
    int have_lp = 0;
    if (wants_cycles_pass(n)) {
        if (ew_find_image_passes(f, layer, &lp, err, sizeof err) != 0 ||
            ew_find_layer_passes(f, layer, &noisy, err, sizeof err) != 0)
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "'%s': %s", path, err);
        have_lp = 1;
    }
    static const char *const names[R_NUM] = {"color", "albedo", "normal", "depth", "z", "vector", "image", "noisy"};
    for (int o = 0; o < R_NUM; o++) {
        if (!ew_node_output_wanted(n, o)) continue;
        const char *pass = NULL, *comps = NULL;
        switch (o) {
        case R_COLOR: pass = have_lp ? lp.color : NULL; comps = "RGB"; break;
        case R_NOISY: pass = have_lp ? noisy.color : NULL; comps = "RGB"; break;
        case R_ALBEDO: pass = have_lp ? lp.albedo : NULL; comps = "RGB"; break;
        case R_NORMAL: pass = have_lp ? lp.normal : NULL; comps = "XYZ"; break;
        case R_DEPTH: pass = have_lp ? lp.depth : NULL; comps = "Z"; break;
        case R_Z: pass = ewio_has_pass(f, layer, "Depth", "Z") ? "Depth" : NULL; comps = "Z"; break;
        case R_VECTOR: pass = ewio_has_pass(f, layer, "Vector", "XYZW") ? "Vector" : NULL; comps = "XYZW"; break;
        default: {
            const char *want = ew_node_str(n, "pass");
            int k = pass_components(f, layer, want, m->comps[o], sizeof m->comps[o]);
            if (k == 0) {
                list_passes(f, layer, passes, sizeof passes);
                return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT,
                                    "parameter 'pass': no pass '%s' in layer '%s' of '%s' (passes: %s)", want, layer,
                                    path, passes);
            }
            if (k > 4)
                return ew_node_fail(n, EW_ERR_UNSUPPORTED, "parameter 'pass': pass '%s' has %d components (at most 4)",
                                    want, k);
            m->pass[o] = want;
            continue;
        }
        }
        if (!pass) {
            static const char *const looked[R_NUM] = {"'Combined'", "'Denoising Albedo', 'DiffCol'",
                                                      "'Denoising Normal', 'Normal'", "'Denoising Depth', 'Depth'",
                                                      "'Depth'", "'Vector'", "", "'Noisy Image', 'Combined'"};
            list_passes(f, layer, passes, sizeof passes);
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT,
                                "output '%s': layer '%s' of '%s' has no %s pass (looked for %s; passes: %s)", names[o],
                                layer, path, names[o], looked[o], passes);
        }
        m->pass[o] = pass;
        snprintf(m->comps[o], sizeof m->comps[o], "%s", comps);
    }
    return EW_OK;
}

static ew_result read_load(ew_gnode *n, int frame, char *path, size_t len) {
    read_state *s = read_state_get(n);
    if (!s) return ew_node_fail(n, EW_ERR_OUT_OF_MEMORY, "out of memory");
    if (!ew_frame_path(ew_node_str(n, "path"), frame, path, len))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'path': too long");
    if (s->file && s->frame == frame && !strcmp(s->path, path)) return EW_OK;
    ewio_free(s->file);
    s->file = NULL;
    char err[1024];
    if (ewio_read(path, &s->file, err, sizeof err) != 0)
        return ew_node_fail(n, EW_ERR_IO, "parameter 'path': %s", err);
    s->frame = frame;
    snprintf(s->path, sizeof s->path, "%s", path);
    return EW_OK;
}

static ew_result read_check_files(ew_gnode *n) {
    ew_graph *g = n->g;
    const char *pattern = ew_node_str(n, "path");
    char path[4096];
    struct stat st;
    int patterned = ew_path_has_pattern(pattern);
    for (int f = 0; f < g->num_frames; f++) {
        if (!ew_frame_path(pattern, g->frames[f], path, sizeof path))
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'path': too long");
        if (stat(path, &st) != 0) {
            if (patterned)
                return ew_node_fail(n, EW_ERR_IO, "parameter 'path': frame %d of '%s' is missing: no file '%s'",
                                    g->frames[f], pattern, path);
            return ew_node_fail(n, EW_ERR_IO, "parameter 'path': no file '%s'", path);
        }
        if (S_ISDIR(st.st_mode)) return ew_node_fail(n, EW_ERR_IO, "parameter 'path': '%s' is a directory", path);
        if (!patterned) break;
    }
    /* The first frame now, kept for the run: passes and layers are checked
     * before anything is written. */
    ew_result r = read_load(n, g->frames[0], path, sizeof path);
    if (r != EW_OK) return r;
    read_state *s = (read_state *)n->state;
    char layer[256];
    if (pick_layer(n, s->file, path, layer, sizeof layer) != 0) return EW_ERR_INVALID_ARGUMENT;
    read_map m;
    return map_passes(n, s->file, path, layer, &m);
}

static ew_result read_execute(ew_gnode *n, ew_run *r) {
    char path[4096], layer[256], err[1024];
    ew_result res = read_load(n, r->frame, path, sizeof path);
    if (res != EW_OK) return res;
    read_state *s = (read_state *)n->state;
    if (pick_layer(n, s->file, path, layer, sizeof layer) != 0) return EW_ERR_INVALID_ARGUMENT;
    snprintf(s->layer, sizeof s->layer, "%s", layer);
    read_map m;
    if ((res = map_passes(n, s->file, path, layer, &m)) != EW_OK) return res;
    const int w = ewio_width(s->file), h = ewio_height(s->file);
    char key[320];
    snprintf(key, sizeof key, "cycles.%s.samples", layer);
    const int spp = atoi(ewio_get_attribute(s->file, key));
    for (int o = 0; o < R_NUM && res == EW_OK; o++) {
        if (!m.pass[o]) continue;
        ew_image v;
        n->out_samples[o] = spp > 0 ? spp : 0;
        res = ew_run_output(r, n, o, w, h, (int)strlen(m.comps[o]), &v);
        if (res == EW_OK && ewio_get_pass(s->file, layer, m.pass[o], m.comps[o], (float *)v.data, err, sizeof err) != 0)
            res = ew_node_fail(n, EW_ERR_IO, "'%s': %s", path, err);
    }
    /* One frame's file in memory at a time: kept for a write that keeps the
     * source, else freed now. */
    if (!s->keep_file || res != EW_OK) {
        ewio_free(s->file);
        s->file = NULL;
    }
    return res;
}

const ew_node_type ew_node_read = {
    "read", 1, "io",
    "read passes of an image file or a frame sequence (Cycles multilayer EXR, EXR, PNG, TIFF)",
    NULL, NULL, NULL, 0, read_outputs, R_NUM, read_params, 3, -1, 0,
    NULL, read_check_files, NULL, read_execute, read_release,
};

/* ---- write --------------------------------------------------------------- */

static const ew_port_desc write_inputs[] = {
    {"image", EW_PASS_ANY, 1, 1, "the image to write (1 to 4 channels)"},
};

static const char *const pixel_types[] = {"half", "float", NULL};

static const ew_nparam_desc write_params[] = {
    {"path", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 1, 1, "Path",
     "output file; the extension picks the format (.exr, .png, .tif, .jpg); a run of '#' or a %04d is the frame "
     "number. Written atomically; never one of the graph's inputs, never the file of another write or frame"},
    {"layer", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Layer",
     "EXR layer name, e.g. 'ViewLayer'; empty: a plain image"},
    {"pass", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Pass",
     "EXR pass name; empty: 'Combined' in a named layer, none in a plain image"},
    {"channels", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Channels",
     "component names, one letter each (e.g. 'XYZ', 'Z'); empty: Y, RG, RGB or RGBA by channel count"},
    {"pixel_type", EW_NODE_PARAM_ENUM, 0, 0, 0, "half", {0, 0, 0, 0}, pixel_types, 0, 0, "Pixel Type",
     "EXR/TIFF sample type (PNG is 8-bit)"},
    {"keep_source", EW_NODE_PARAM_BOOL, 0, 0, 1, "", {0, 0, 0, 0}, NULL, 0, 0, "Keep Source",
     "start from the file the image was read from (the read node upstream, this frame): every layer, pass, "
     "alpha and header entry stays, and the image replaces 'pass' of 'layer' (empty: the read layer's "
     "Combined), as `edgewise denoise` does. Write .exr for a multilayer file"},
    {"original", EW_NODE_PARAM_STRING, 0, 0, 0, "", {0, 0, 0, 0}, NULL, 0, 0, "Keep Original As",
     "with keep_source: also keep the replaced pass's original values as this pass, e.g. 'Noisy Image' (as "
     "Blender and `edgewise denoise` do); empty: not kept"},
};

static ew_result write_check(ew_gnode *n) {
    const char *ch = ew_node_str(n, "channels");
    size_t len = strlen(ch);
    if (len > 4) return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'channels': '%s' has more than 4 letters", ch);
    for (size_t i = 0; i < len; i++) {
        if (!((ch[i] >= 'A' && ch[i] <= 'Z') || (ch[i] >= 'a' && ch[i] <= 'z')))
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'channels': '%s' must be letters only", ch);
        if (strchr(ch + i + 1, ch[i]))
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'channels': '%s' repeats '%c'", ch, ch[i]);
    }
    if (strchr(ew_node_str(n, "pass"), '.'))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'pass': a pass name cannot contain '.'");
    if (strchr(ew_node_str(n, "original"), '.'))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'original': a pass name cannot contain '.'");
    if (ew_node_str(n, "original")[0] && ew_node_num(n, "keep_source") == 0.0)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'original' needs keep_source: true");
    return EW_OK;
}

/* The read node the image comes from: up the graph from input `port`,
 * through the first connected input of each node on the way (a library
 * node's "color" first). NULL if no read is upstream. */
static ew_gnode *upstream_read(const ew_gnode *n, int port) {
    const ew_graph *g = n->g;
    int at = n->src_node[port];
    for (int hops = 0; at >= 0 && hops <= g->num_nodes; hops++) {
        ew_gnode *u = g->nodes[at];
        if (!strcmp(u->type->name, "read")) return u;
        int next = -1, c = ew_sig_find_input(&u->sig, "color");
        if (c >= 0 && u->src_node[c] >= 0) next = u->src_node[c];
        for (int p = 0; next < 0 && p < u->sig.num_inputs; p++)
            if (u->src_node[p] >= 0) next = u->src_node[p];
        at = next;
    }
    return NULL;
}

/* The output directory must exist and be writable before anything runs. */
static ew_result write_check_files(ew_gnode *n) {
    char path[4096], dir[4096];
    if (!ew_frame_path(ew_node_str(n, "path"), n->g->frames[0], path, sizeof path))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'path': too long");
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash) snprintf(dir, sizeof dir, ".");
    else if (slash == dir) dir[1] = '\0';
    else *slash = '\0';
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return ew_node_fail(n, EW_ERR_IO, "parameter 'path': cannot write '%s': directory '%s' does not exist", path,
                            dir);
    if (access(dir, W_OK) != 0)
        return ew_node_fail(n, EW_ERR_IO, "parameter 'path': cannot write '%s': directory '%s' is not writable", path,
                            dir);
    if (ew_node_num(n, "keep_source") != 0.0) {
        ew_gnode *rn = upstream_read(n, 0);
        if (!rn)
            return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT,
                                "parameter 'keep_source': input 'image' does not come from a read node, so there is no "
                                "source file to keep");
        read_state *rs = read_state_get(rn);
        if (!rs) return ew_node_fail(n, EW_ERR_OUT_OF_MEMORY, "out of memory");
        rs->keep_file = 1;
    }
    const char *ext = strrchr(path, '.');
    if (!ext || (strcasecmp(ext, ".exr") && strcasecmp(ext, ".png") && strcasecmp(ext, ".tif") &&
                 strcasecmp(ext, ".tiff") && strcasecmp(ext, ".jpg") && strcasecmp(ext, ".jpeg")))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT,
                            "parameter 'path': '%s' needs an extension .exr, .png, .tif/.tiff or .jpg", path);
    return EW_OK;
}

/* Open the source file of this frame and say where the image goes. */
static ew_result keep_source_open(ew_gnode *n, ew_run *r, const ew_image *im, ewio_file **f, const char **layer,
                                  const char **pass) {
    ew_gnode *rn = upstream_read(n, 0);
    if (!rn || !rn->state)
        return ew_node_fail(n, EW_ERR_INVALID_STATE, "parameter 'keep_source': no read node upstream ran");
    read_state *rs = (read_state *)rn->state;
    char src[4096], err[1024];
    if (!ew_frame_path(ew_node_str(rn, "path"), r->frame, src, sizeof src))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'path': too long");
    if (rs->file && rs->frame == r->frame && !strcmp(rs->path, src)) { /* the read kept it: take it */
        *f = rs->file;
        rs->file = NULL;
    } else if (ewio_read(src, f, err, sizeof err) != 0) {
        return ew_node_fail(n, EW_ERR_IO, "keep_source: %s", err);
    }
    if (ewio_width(*f) != im->width || ewio_height(*f) != im->height) {
        const int fw = ewio_width(*f), fh = ewio_height(*f);
        ewio_free(*f);
        *f = NULL;
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "keep_source: the image is %dx%d but '%s' is %dx%d",
                            im->width, im->height, src, fw, fh);
    }
    if (!(*layer)[0]) *layer = rs->layer;
    if (!(*pass)[0]) {
        ew_layer_passes lp;
        *pass = (*layer)[0] ? "Combined"
                            : ew_find_image_passes(*f, *layer, &lp, err, sizeof err) == 0 ? lp.color : "";
    }
    return EW_OK;
}

static ew_result write_execute(ew_gnode *n, ew_run *r) {
    const ew_image *im = ew_node_in(n, "image");
    char path[4096], err[1024];
    if (!ew_frame_path(ew_node_str(n, "path"), r->frame, path, sizeof path))
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'path': too long");
    const char *layer = ew_node_str(n, "layer");
    const char *pass = ew_node_str(n, "pass");
    const int keep = ew_node_num(n, "keep_source") != 0.0;
    ewio_file *f = NULL;
    if (keep) {
        ew_result kr = keep_source_open(n, r, im, &f, &layer, &pass);
        if (kr != EW_OK) return kr;
    }
    if (layer[0] && !pass[0]) pass = "Combined";
    const char *comps = ew_node_str(n, "channels");
    static const char *const auto_comps[] = {"", "Y", "RG", "RGB", "RGBA"};
    if (!comps[0]) comps = auto_comps[im->channels];
    if ((int)strlen(comps) != im->channels) {
        ewio_free(f);
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "parameter 'channels': '%s' names %d channels but the image has %d",
                            comps, (int)strlen(comps), im->channels);
    }
    if (!f && ewio_create(im->width, im->height, &f, err, sizeof err) != 0)
        return ew_node_fail(n, EW_ERR_IO, "frame %d: %s", r->frame, err);
    /* the replaced values kept under another name, before they go */
    const char *orig = ew_node_str(n, "original");
    if (keep && orig[0] && strcmp(orig, pass) != 0 && !ewio_has_pass(f, layer, orig, comps) &&
        ewio_has_pass(f, layer, pass, comps)) {
        const char *oc = ewio_has_pass(f, layer, pass, "RGBA") ? "RGBA" : comps;
        float *o = (float *)malloc((size_t)im->width * im->height * strlen(oc) * sizeof(float));
        if (!o) snprintf(err, sizeof err, "out of memory");
        int bad = !o || ewio_get_pass(f, layer, pass, oc, o, err, sizeof err) != 0 ||
                  ewio_set_pass(f, layer, orig, oc, o, err, sizeof err) != 0;
        free(o);
        if (bad) {
            ewio_free(f);
            return ew_node_fail(n, EW_ERR_IO, "parameter 'original': frame %d: %s", r->frame, err);
        }
    }
    /* ewio takes packed pixels; graph buffers are, caller views may not be */
    const ew_image *src = im;
    float *tmp = NULL;
    int packed = (im->pixel_stride == 0 || im->pixel_stride == (int64_t)im->channels * 4) &&
                 (im->row_stride == 0 || im->row_stride == (int64_t)im->channels * 4 * im->width);
    if (!packed) {
        tmp = (float *)malloc((size_t)im->width * im->height * im->channels * sizeof(float));
        if (!tmp) {
            ewio_free(f);
            return ew_node_fail(n, EW_ERR_OUT_OF_MEMORY, "out of memory");
        }
        for (int y = 0; y < im->height; y++)
            for (int x = 0; x < im->width; x++)
                memcpy(tmp + ((size_t)y * im->width + x) * im->channels, ew_px(im, x, y), (size_t)im->channels * 4);
    }
    const float *data = tmp ? tmp : (const float *)src->data;
    ew_result res = EW_OK;
    if (ewio_set_pass(f, layer, pass, comps, data, err, sizeof err) != 0)
        res = ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "frame %d: %s", r->frame, err);
    if (!keep) ewio_set_attribute(f, "Software", "edgewise graph");
    else ewio_set_attribute(f, "edgewise.version", ew_version_string());
    /* a kept file's passes keep their types; new ones are half or float */
    ewio_pixel_type pt = ew_node_num(n, "pixel_type") == 1.0 ? EWIO_FLOAT : keep ? EWIO_KEEP : EWIO_HALF;
    if (res == EW_OK && ewio_write(f, path, pt, layer, pass, err, sizeof err) != 0)
        res = ew_node_fail(n, EW_ERR_IO, "frame %d: %s", r->frame, err);
    if (res == EW_OK) ew_run_report_written(r, path);
    free(tmp);
    ewio_free(f);
    return res;
}

const ew_node_type ew_node_write = {
    "write", 1, "io", "write an image file atomically (EXR, PNG, TIFF), one per frame",
    NULL, NULL, write_inputs, 1, NULL, 0, write_params, 7, -1, 1,
    write_check, write_check_files, NULL, write_execute, NULL,
};

/* ---- input / output (caller memory) -------------------------------------- */

static const ew_port_desc input_outputs[] = {
    {"image", EW_PASS_ANY, 1, 0, "the caller's image (ew_graph_set_input), not copied"},
};

static ew_result input_execute(ew_gnode *n, ew_run *r) {
    (void)r;
    if (!n->has_ext) return ew_node_fail(n, EW_ERR_INVALID_STATE, "no image given (ew_graph_set_input)");
    n->out[0] = n->ext;
    n->out_buf[0] = -1;
    n->has_out[0] = 1;
    return EW_OK;
}

const ew_node_type ew_node_input = {
    "input", 1, "io", "an image in caller memory (C API, Python arrays)",
    NULL, NULL, NULL, 0, input_outputs, 1, NULL, 0, -1, 0,
    NULL, NULL, NULL, input_execute, NULL,
};

static const ew_port_desc output_inputs[] = {
    {"image", EW_PASS_ANY, 1, 1, "the image handed back to the caller"},
};

static ew_result output_execute(ew_gnode *n, ew_run *r) {
    (void)r;
    const ew_image *im = ew_node_in(n, "image");
    if (!n->has_ext) return EW_OK; /* kept in graph memory: ew_graph_get_output */
    const ew_image *d = &n->ext;
    if (d->width != im->width || d->height != im->height || d->channels != im->channels)
        return ew_node_fail(n, EW_ERR_INVALID_ARGUMENT, "the result is %dx%d with %d channels but the given image is "
                            "%dx%d with %d", im->width, im->height, im->channels, d->width, d->height, d->channels);
    for (int y = 0; y < im->height; y++)
        for (int x = 0; x < im->width; x++) memcpy(ew_px(d, x, y), ew_px(im, x, y), (size_t)im->channels * 4);
    return EW_OK;
}

const ew_node_type ew_node_output = {
    "output", 1, "io", "hand an image back to the caller (C API, Python arrays)",
    NULL, NULL, output_inputs, 1, NULL, 0, NULL, 0, -1, 1,
    NULL, NULL, NULL, output_execute, NULL,
};

void ew_nodes_remove_temporaries(void) { ewio_remove_temporaries(); }
