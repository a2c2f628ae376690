/* A C host of shadowcull: it keeps its own arrays (a unit cube, a ground
 * slab and a grid of boxes, two lights), uploads them once, and every frame
 * of a camera path hands the pipeline its view and projection matrices
 * (OpenGL conventions), moving one box, removing one and adding one along the
 * way. It prints per frame the PSR and PSC counts and the volume triangles,
 * and last one JSON line.
 *
 *   make -C examples/c run       (builds the library, runs under valgrind)
 */
#include "shadowcull.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FRAMES 30
#define WIDTH 160
#define HEIGHT 120
#define OBJECTS 37

#define CHECK(call)                                                        \
  do {                                                                     \
    sc_status s_ = (call);                                                 \
    if (s_ != SC_OK) {                                                     \
      fprintf(stderr, "%s:%d: %s -> %d: %s\n", __FILE__, __LINE__, #call, \
              (int)s_, sc_last_error());                                   \
      exit(1);                                                             \
    }                                                                      \
  } while (0)

/* Column-major 4x4: scale then translate. */
static void placement(int k, double m[16]) {
  double sx = 1.5, sy = 1.0 + (k % 4), sz = 1.5, tx, ty = 0.0, tz;
  if (k == 0) {
    sx = 40.0, sy = 0.5, sz = 40.0, tx = -20.0, ty = -0.5, tz = -20.0;
  } else {
    tx = -15.0 + 5.0 * ((k - 1) % 6);
    tz = -15.0 + 5.0 * ((k - 1) / 6);
  }
  memset(m, 0, 16 * sizeof(double));
  m[0] = sx, m[5] = sy, m[10] = sz, m[15] = 1.0;
  m[12] = tx, m[13] = ty, m[14] = tz;
}

/* The view (right-handed look-at) and OpenGL projection of frame f. */
static void matrices(int f, double view[16], double proj[16]) {
  double a = f * 0.15, e[3] = {25.0 * cos(a), 9.0, 25.0 * sin(a)};
  double fw[3] = {-e[0], 1.0 - e[1], -e[2]}, r[3], u[3];
  double n = sqrt(fw[0] * fw[0] + fw[1] * fw[1] + fw[2] * fw[2]);
  for (int i = 0; i < 3; i++) fw[i] /= n;
  r[0] = -fw[2], r[1] = 0.0, r[2] = fw[0]; /* f x (0,1,0) */
  n = sqrt(r[0] * r[0] + r[2] * r[2]);
  r[0] /= n, r[2] /= n;
  u[0] = r[1] * fw[2] - r[2] * fw[1];
  u[1] = r[2] * fw[0] - r[0] * fw[2];
  u[2] = r[0] * fw[1] - r[1] * fw[0];
  memset(view, 0, 16 * sizeof(double));
  for (int i = 0; i < 3; i++) {
    view[4 * i + 0] = r[i], view[4 * i + 1] = u[i], view[4 * i + 2] = -fw[i];
  }
  view[12] = -(r[0] * e[0] + r[1] * e[1] + r[2] * e[2]);
  view[13] = -(u[0] * e[0] + u[1] * e[1] + u[2] * e[2]);
  view[14] = fw[0] * e[0] + fw[1] * e[1] + fw[2] * e[2];
  view[15] = 1.0;
  double near = 0.1, far = 200.0, t = 1.0 / tan(30.0 * 3.14159265358979323846 / 180.0);
  memset(proj, 0, 16 * sizeof(double));
  proj[0] = t / ((double)WIDTH / HEIGHT), proj[5] = t;
  proj[10] = -(far + near) / (far - near), proj[11] = -1.0;
  proj[14] = -2.0 * far * near / (far - near);
}

static int cmp(const void *a, const void *b) {
  size_t x = *(const size_t *)a, y = *(const size_t *)b;
  return (x > y) - (x < y);
}

static size_t median(size_t *v, int n) {
  qsort(v, n, sizeof *v, cmp);
  return v[n / 2];
}

int main(void) {
  /* The host's cube: 8 corners (float), 12 triangles (uint16). */
  float corners[8][3];
  for (int i = 0; i < 8; i++) {
    corners[i][0] = (float)(i & 1), corners[i][1] = (float)((i >> 1) & 1);
    corners[i][2] = (float)((i >> 2) & 1);
  }
  static const uint16_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  uint16_t indices[36];
  for (int q = 0; q < 6; q++) {
    const uint16_t *c = quads[q];
    uint16_t t[6] = {c[0], c[1], c[2], c[0], c[2], c[3]};
    memcpy(indices + 6 * q, t, sizeof t);
  }

  sc_pipeline_options options;
  CHECK(sc_pipeline_options_default(&options));
  options.stencil = SC_STENCIL_H; /* a GPU host keeps SC_STENCIL_NONE */
  options.light_resolution = 256;
  sc_pipeline p = 0;
  CHECK(sc_pipeline_create(&options, &p));

  sc_mesh_desc mesh = {sizeof(sc_mesh_desc)};
  mesh.position_type = SC_F32, mesh.position_stride = sizeof corners[0];
  mesh.vertex_count = 8, mesh.positions = corners;
  mesh.index_type = SC_U16, mesh.index_count = 36, mesh.indices = indices;
  sc_mesh cube = 0;
  CHECK(sc_mesh_create(p, &mesh, &cube));

  sc_object objects[OBJECTS + 1];
  for (int k = 0; k < OBJECTS; k++) {
    double m[16];
    placement(k, m);
    CHECK(sc_object_create(p, cube, m, SC_FLAGS_ALL, &objects[k]));
  }
  sc_light_desc point = {sizeof(sc_light_desc), SC_LIGHT_POINT, {2.0, 14.0, 3.0}};
  sc_light_desc sun = {sizeof(sc_light_desc), SC_LIGHT_DIRECTIONAL, {0}, {0.4, -0.8, 0.3}};
  sc_light lights[2];
  CHECK(sc_light_create(p, &point, &lights[0]));
  CHECK(sc_light_create(p, &sun, &lights[1]));

  size_t psr[FRAMES], psc[FRAMES], tris[FRAMES];
  sc_frame_input in = {sizeof(sc_frame_input), WIDTH, HEIGHT, SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE};
  sc_frame_output out = {sizeof(sc_frame_output)};
  for (int f = 0; f < FRAMES; f++) {
    double m[16];
    placement(5, m);
    m[12] += 0.3 * f; /* box 5 slides along x */
    CHECK(sc_object_set_transform(p, objects[5], m));
    if (f == 3) CHECK(sc_object_destroy(p, objects[7]));
    if (f == 4) {
      placement(7, m);
      m[13] += 2.0; /* a box floats where box 7 stood */
      CHECK(sc_object_create(p, cube, m, SC_FLAGS_ALL, &objects[OBJECTS]));
    }
    matrices(f, in.view, in.projection);
    CHECK(sc_pipeline_frame(p, &in, &out));
    psr[f] = out.psr_count, psc[f] = 0, tris[f] = 0;
    for (size_t l = 0; l < out.light_count; l++) {
      const sc_light_output *lo = &out.lights[l];
      psc[f] += lo->psc_count;
      for (size_t r = 0; r < lo->range_count; r++) {
        /* Bind world_from_local, set the method's stencil ops, scissor and
           depth bounds, and draw this range's triangles: */
        tris[f] += lo->ranges[r].index_count / 3;
      }
    }
    printf("frame %d psr %zu psc %zu volume_triangles %zu\n", f, psr[f], psc[f], tris[f]);
  }
  CHECK(sc_pipeline_destroy(p));
  printf("{\"frames\":%d,\"psr_median\":%zu,\"psc_median\":%zu,\"volume_triangles_median\":%zu}\n",
         FRAMES, median(psr, FRAMES), median(psc, FRAMES), median(tris, FRAMES));
  return 0;
}
