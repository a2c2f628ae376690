/* A C host of shadowcull: the same scene, path and edits as
 * examples/host_loop.rs, from the host's own arrays (the same generator
 * constants): a ground quad and 506 cubes and towers, a point light and a
 * sun; every frame it hands the pipeline its OpenGL view and jittered
 * projection matrices, moves one object, and early on removes one and adds
 * an invisible shadow proxy. It prints per frame the PSR and PSC counts and
 * the volume triangles, and last one JSON line.
 *
 *   host [--write-masks DIR]   each frame's masks as binary PGM (P5), one
 *                              byte per pixel: 0 lit, 1 shadow, 2 unlit,
 *                              3 background, and its id lists and volume
 *                              buffers; host_loop --write-masks writes the
 *                              same files.
 *   make -C examples/c run     builds, runs under valgrind, compares masks.
 */
#define _POSIX_C_SOURCE 199309L
#include "shadowcull.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define FRAMES 30
#define WIDTH 320
#define HEIGHT 240
#define GRID_X 22
#define GRID_Z 23
#define OBJECTS (1 + GRID_X * GRID_Z)
#define PI 3.14159265358979323846

#define CHECK(call)                                                        \
  do {                                                                     \
    sc_status s_ = (call);                                                 \
    if (s_ != SC_OK) {                                                     \
      fprintf(stderr, "%s:%d: %s -> %d: %s\n", __FILE__, __LINE__, #call, \
              (int)s_, sc_last_error());                                   \
      exit(1);                                                             \
    }                                                                      \
  } while (0)

/* Column-major 4x4 of doubles, as the pipeline takes them. */
typedef struct { double m[16]; } mat4;

/* scale, then a rotation of `angle` about +y, then translate: the float
 * operations in the order of glam's DMat4::from_scale_rotation_translation
 * with DQuat::from_rotation_y. */
static mat4 srt_y(double sx, double sy, double sz, double angle, double tx, double ty, double tz) {
  double x = 0.0, y = sin(angle * 0.5), z = 0.0, w = cos(angle * 0.5);
  double x2 = x + x, y2 = y + y, z2 = z + z;
  double xx = x * x2, xy = x * y2, xz = x * z2, yy = y * y2, yz = y * z2, zz = z * z2;
  double wx = w * x2, wy = w * y2, wz = w * z2;
  mat4 r = {{(1.0 - (yy + zz)) * sx, (xy + wz) * sx, (xz - wy) * sx, 0.0,
             (xy - wz) * sy, (1.0 - (xx + zz)) * sy, (yz + wx) * sy, 0.0,
             (xz + wy) * sz, (yz - wx) * sz, (1.0 - (xx + yy)) * sz, 0.0,
             tx, ty, tz, 1.0}};
  return r;
}

/* a * b, each column as glam sums it: ((x·c.x + y·c.y) + z·c.z) + w·c.w. */
static mat4 mul(const mat4 *a, const mat4 *b) {
  mat4 r;
  for (int c = 0; c < 4; c++) {
    for (int k = 0; k < 4; k++) {
      double v = a->m[0 + k] * b->m[4 * c + 0];
      v = v + a->m[4 + k] * b->m[4 * c + 1];
      v = v + a->m[8 + k] * b->m[4 * c + 2];
      v = v + a->m[12 + k] * b->m[4 * c + 3];
      r.m[4 * c + k] = v;
    }
  }
  return r;
}

typedef struct { double x, y, z; } vec3;

static double dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

static vec3 cross(vec3 a, vec3 b) {
  vec3 r = {a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y};
  return r;
}

static vec3 normalize(vec3 v) {
  double k = 1.0 / sqrt(dot(v, v));
  vec3 r = {v.x * k, v.y * k, v.z * k};
  return r;
}

static double halton(unsigned i, unsigned b) {
  double r = 0.0, f = 1.0;
  while (i > 0) {
    f /= (double)b;
    r += f * (double)(i % b);
    i /= b;
  }
  return r - 0.5;
}

/* The view and projection of frame f of n: down a street, rising at the end;
 * OpenGL-style, with a far plane and a TAA jitter. */
static void host_matrices(unsigned f, unsigned n, double view[16], double proj[16]) {
  double t = (double)f / (double)((n < 2 ? 2 : n) - 1);
  vec3 eye = {-95.0 + 170.0 * t, 2.0 + 25.0 * t * t, 4.0};
  vec3 d0 = {1.0, -0.15 - 0.4 * t * t, 0.25 * sin(6.0 * t)};
  vec3 dir = normalize(d0), yaxis = {0.0, 1.0, 0.0};
  vec3 side = normalize(cross(dir, yaxis));
  vec3 up = cross(side, dir);
  double v[16] = {side.x, up.x, -dir.x, 0.0, side.y, up.y, -dir.y, 0.0,
                  side.z, up.z, -dir.z, 0.0, -dot(side, eye), -dot(up, eye), dot(dir, eye), 1.0};
  memcpy(view, v, sizeof v);
  double near = 0.1, far = 2000.0, fy = 1.0 / tan(30.0 * (PI / 180.0));
  double jx = 2.0 * halton(f + 1, 2) / (double)WIDTH;
  double jy = 2.0 * halton(f + 1, 3) / (double)HEIGHT;
  double p[16] = {fy * (double)HEIGHT / (double)WIDTH, 0, 0, 0, 0, fy, 0, 0,
                  jx, jy, -(far + near) / (far - near), -1.0,
                  0, 0, -2.0 * far * near / (far - near), 0};
  memcpy(proj, p, sizeof p);
}

static uint32_t seed = 0x2545f491u;

static double rnd(void) {
  seed ^= seed << 13;
  seed ^= seed >> 17;
  seed ^= seed << 5;
  return (double)seed / (double)UINT32_MAX;
}

static sc_mesh upload(sc_pipeline p, const float (*pos)[3], uint32_t n, const uint32_t *idx,
                      uint32_t count) {
  sc_mesh_desc d = {sizeof d, SC_F32, sizeof pos[0], n, pos, SC_U32, count, idx};
  sc_mesh m = 0;
  CHECK(sc_mesh_create(p, &d, &m));
  return m;
}

static int cmp(const void *a, const void *b) {
  size_t x = *(const size_t *)a, y = *(const size_t *)b;
  return (x > y) - (x < y);
}

static int cmp_f(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

static double median_f(double *v, int n) {
  qsort(v, n, sizeof *v, cmp_f);
  return v[n / 2];
}

static double now_ms(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
}

static size_t median(size_t *v, int n) {
  qsort(v, n, sizeof *v, cmp);
  return v[n / 2];
}

/* Writes n little-endian u32 values (this host is little-endian, as x86-64 and
 * AArch64 are) to DIR/frame_FFF_NAME.bin, after `extra` bytes of head. */
static void write_bin(const char *dir, int f, const char *name, const void *head, size_t extra,
                      const uint32_t *v, size_t n) {
  char path[4096];
  snprintf(path, sizeof path, "%s/frame_%03d_%s.bin", dir, f, name);
  FILE *o = fopen(path, "wb");
  if (!o) {
    perror(path);
    exit(1);
  }
  if (extra) fwrite(head, 1, extra, o);
  if (n) fwrite(v, sizeof *v, n, o);
  fclose(o);
}

/* Frame f's id lists and volume buffers as host_loop --write-masks writes
 * them: object slots as u32; per light the positions, the indices,
 * then per range its object's slot, method, first index and index count. */
/* An object's slot, as host_loop writes it. Only this comparison needs it: a
 * host treats handles as opaque. (The library's layout: handle - 1 holds the
 * slot in bits 0-27, the kind in 28-31 and the generation above.) */
static uint32_t slot_of(sc_object h) { return (uint32_t)((h - 1) & 0x0fffffffu); }

static void write_outputs(const char *dir, int f, const sc_frame_output *out) {
  uint32_t *ids = malloc((out->psr_count + 1) * sizeof *ids);
  for (size_t i = 0; i < out->psr_count; i++) ids[i] = slot_of(out->psr[i]);
  write_bin(dir, f, "psr", NULL, 0, ids, out->psr_count);
  free(ids);
  for (size_t l = 0; l < out->light_count; l++) {
    const sc_light_output *lo = &out->lights[l];
    char name[64];
    ids = malloc((lo->psc_count + 1) * sizeof *ids);
    for (size_t i = 0; i < lo->psc_count; i++) ids[i] = slot_of(lo->psc[i]);
    snprintf(name, sizeof name, "light_%zu_psc", l);
    write_bin(dir, f, name, NULL, 0, ids, lo->psc_count);
    free(ids);
    size_t n = lo->index_count + 4 * lo->range_count;
    uint32_t *v = malloc((n + 1) * sizeof *v);
    memcpy(v, lo->indices, lo->index_count * sizeof *v);
    for (size_t r = 0; r < lo->range_count; r++) {
      const sc_volume_range *g = &lo->ranges[r];
      uint32_t *w = v + lo->index_count + 4 * r;
      w[0] = slot_of(g->object), w[1] = g->method, w[2] = g->first_index;
      w[3] = g->index_count;
    }
    snprintf(name, sizeof name, "light_%zu_volumes", l);
    write_bin(dir, f, name, lo->positions, lo->position_count * sizeof *lo->positions, v, n);
    free(v);
  }
}

static void write_mask(const char *dir, int f, size_t l, const uint8_t *mask) {
  char path[4096];
  snprintf(path, sizeof path, "%s/frame_%03d_light_%zu.pgm", dir, f, l);
  FILE *o = fopen(path, "wb");
  if (!o) {
    perror(path);
    exit(1);
  }
  fprintf(o, "P5\n%d %d\n3\n", WIDTH, HEIGHT);
  fwrite(mask, 1, (size_t)WIDTH * HEIGHT, o);
  fclose(o);
}

int main(int argc, char **argv) {
  const char *masks = NULL;
  if (argc == 3 && !strcmp(argv[1], "--write-masks")) {
    masks = argv[2];
  } else if (argc != 1) {
    fprintf(stderr, "usage: host [--write-masks DIR]\n");
    return 2;
  }
  /* The host's meshes: a unit cube standing on y = 0, a tower (its top
   * narrowed to 60 %), the ground. */
  float cube[8][3], tower[8][3];
  for (int i = 0; i < 8; i++) {
    cube[i][0] = (float)(i & 1) - 0.5f;
    cube[i][1] = (float)((i >> 1) & 1);
    cube[i][2] = (float)((i >> 2) & 1) - 0.5f;
    memcpy(tower[i], cube[i], sizeof cube[i]);
    if (tower[i][1] == 1.0f) tower[i][0] *= 0.6f, tower[i][2] *= 0.6f;
  }
  static const uint32_t faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  uint32_t box_idx[36];
  for (int q = 0; q < 6; q++) {
    const uint32_t *c = faces[q];
    uint32_t t[6] = {c[0], c[1], c[2], c[0], c[2], c[3]};
    memcpy(box_idx + 6 * q, t, sizeof t);
  }
  float ground[4][3] = {{-120, 0, -120}, {-120, 0, 120}, {120, 0, 120}, {120, 0, -120}};
  uint32_t ground_idx[6] = {0, 1, 2, 0, 2, 3};

  sc_pipeline_options options;
  CHECK(sc_pipeline_options_default(&options));
  options.stencil = SC_STENCIL_H; /* a GPU host keeps SC_STENCIL_NONE */
  sc_pipeline p = 0;
  CHECK(sc_pipeline_create(&options, &p));
  /* Room for every object and the proxy added later, and two lights: adding
     into it allocates nothing and refits the culling hierarchy. */
  CHECK(sc_pipeline_reserve(p, OBJECTS + 1, 2));
  sc_mesh meshes[3] = {upload(p, ground, 4, ground_idx, 6), upload(p, cube, 8, box_idx, 36),
                       upload(p, tower, 8, box_idx, 36)};

  static mat4 world[OBJECTS];
  static sc_object objects[OBJECTS + 1];
  world[0] = srt_y(1, 1, 1, 0, 0, 0, 0); /* the identity */
  CHECK(sc_object_create(p, meshes[0], world[0].m, SC_FLAGS_ALL, &objects[0]));
  int k = 1;
  for (int i = 0; i < GRID_X; i++) {
    for (int j = 0; j < GRID_Z; j++, k++) {
      double x = ((double)i - 10.5) * 9.0, z = ((double)j - 11.0) * 8.0;
      double w = 2.0 + 3.0 * rnd(), d = 2.0 + 3.0 * rnd(), h = 2.0 + 14.0 * rnd();
      int mesh = 1 + (rnd() < 0.3);
      world[k] = srt_y(w, h, d, rnd() * 0.8, x, 0.0, z);
      /* Every 25th object shows no shadows on itself. */
      uint32_t flags = k % 25 ? SC_FLAGS_ALL : SC_FLAGS_ALL & ~SC_RECEIVES;
      CHECK(sc_object_create(p, meshes[mesh], world[k].m, flags, &objects[k]));
    }
  }
  sc_light_desc point = {sizeof point, SC_LIGHT_POINT, {15.0, 70.0, -10.0}};
  sc_light_desc sun = {sizeof sun, SC_LIGHT_DIRECTIONAL, {0}, {-0.45, -1.0, -0.3}};
  sc_light lights[2];
  CHECK(sc_light_create(p, &point, &lights[0]));
  CHECK(sc_light_create(p, &sun, &lights[1]));

  size_t psr[FRAMES], psc[FRAMES], tris[FRAMES];
  /* Wall time of each sc_pipeline_frame call, the pipeline's own frame time
     inside it, and their difference: what the C path adds. */
  double wall[FRAMES], inner[FRAMES], extra[FRAMES];
  sc_frame_input in = {sizeof in, WIDTH, HEIGHT, SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE};
  in.near = 0.1; /* the projection's near plane: a wrong clip-depth convention is refused */
  sc_frame_output out = {sizeof out};
  for (int f = 0; f < FRAMES; f++) {
    /* Object 1 circles its lot; early on the object beside the street goes
     * and an invisible tower (a shadow proxy) appears. */
    double a = (double)f * 0.2;
    mat4 shift = srt_y(1, 1, 1, 0, 3.0 * cos(a), 0.0, 3.0 * sin(a));
    mat4 moved = mul(&shift, &world[1]);
    CHECK(sc_object_set_transform(p, objects[1], moved.m));
    if (f == 1) CHECK(sc_object_destroy(p, objects[12]));
    if (f == 2) {
      mat4 proxy = srt_y(3.0, 12.0, 3.0, 0.0, -10.0, 0.0, 8.5);
      CHECK(sc_object_create(p, meshes[2], proxy.m, SC_FLAGS_ALL & ~SC_VISIBLE,
                             &objects[OBJECTS]));
    }
    host_matrices((unsigned)f, FRAMES, in.view, in.projection);
    double t0 = now_ms();
    CHECK(sc_pipeline_frame(p, &in, &out));
    wall[f] = now_ms() - t0, inner[f] = out.stats.frame_ms, extra[f] = wall[f] - inner[f];
    psr[f] = out.psr_count, psc[f] = 0, tris[f] = 0;
    for (size_t l = 0; l < out.light_count; l++) {
      const sc_light_output *lo = &out.lights[l];
      psc[f] += lo->psc_count;
      for (size_t r = 0; r < lo->range_count; r++) {
        /* Bind world_from_local, set the method's stencil ops, the scissor
           (the band, cut to the optional scissor) and depth bounds, and draw
           this range's triangles: */
        tris[f] += lo->ranges[r].index_count / 3;
      }
      if (masks) write_mask(masks, f, l, lo->mask);
    }
    if (masks) write_outputs(masks, f, &out);
    printf("frame %d psr %zu psc %zu volume_triangles %zu\n", f, psr[f], psc[f], tris[f]);
  }
  CHECK(sc_pipeline_destroy(p));
  /* Timings go to stderr: stdout is compared between builds. */
  fprintf(stderr, "{\"frame_ms_median\":%.4f,\"pipeline_frame_ms_median\":%.4f,\"c_path_ms_median\":%.4f}\n",
          median_f(wall, FRAMES), median_f(inner, FRAMES), median_f(extra, FRAMES));
  printf("{\"frames\":%d,\"psr_median\":%zu,\"psc_median\":%zu,\"volume_triangles_median\":%zu}\n",
         FRAMES, median(psr, FRAMES), median(psc, FRAMES), median(tris, FRAMES));
  return 0;
}
