/* Misuse of the C ABI: every call below is wrong and must come back with the
 * right status and a message, never a crash. Exits 0 when all do. */
#include "shadowcull.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static int failures = 0;

static void expect(sc_status got, sc_status want, const char *what, const char *word) {
  const char *msg = sc_last_error();
  if (got != want || (word && !strstr(msg, word))) {
    fprintf(stderr, "misuse: %s: status %d (want %d), message \"%s\" (want \"%s\")\n", what,
            (int)got, (int)want, msg, word ? word : "");
    failures++;
  }
}

int main(void) {
  sc_pipeline_options o;
  sc_pipeline p = 0, q = 0;
  expect(sc_pipeline_options_default(NULL), SC_INVALID_ARGUMENT, "default(NULL)", "options");
  expect(sc_pipeline_options_default(&o), SC_OK, "default", NULL);
  expect(sc_pipeline_create(NULL, &p), SC_INVALID_ARGUMENT, "create(NULL)", "options: NULL");
  expect(sc_pipeline_create(&o, NULL), SC_INVALID_ARGUMENT, "create(.., NULL)", "out");
  o.struct_size = 2;
  expect(sc_pipeline_create(&o, &p), SC_INVALID_ARGUMENT, "struct_size 2", "struct_size");
  o.struct_size = sizeof o;
  o.culling = 42;
  expect(sc_pipeline_create(&o, &p), SC_INVALID_ARGUMENT, "culling 42", "culling");
  o.culling = SC_CULLING_CHCPP;
  expect(sc_pipeline_create(&o, &p), SC_OK, "create", NULL);

  /* A frame before any object exists, and a 0x0 viewport. */
  sc_frame_input in = {sizeof in, 64, 48, SC_CLIP_DEPTH_NEGATIVE_ONE_TO_ONE};
  /* A 90-degree OpenGL perspective for the viewport's 4:3 aspect. */
  double proj[16] = {0.75, 0, 0, 0, 0, 1.0, 0, 0, 0, 0, -1.002, -1.0, 0, 0, -0.2002, 0};
  double view[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, -1, -10, 1};
  memcpy(in.view, view, sizeof view);
  memcpy(in.projection, proj, sizeof proj);
  sc_frame_output out = {sizeof out};
  expect(sc_pipeline_frame(p, &in, &out), SC_OK, "frame before any object", NULL);
  in.width = in.height = 0;
  expect(sc_pipeline_frame(p, &in, &out), SC_INVALID_ARGUMENT, "0x0 viewport", "viewport");
  /* A square viewport for the 4:3 projection: refused, unless its pixels are not square. */
  in.width = in.height = 64;
  expect(sc_pipeline_frame(p, &in, &out), SC_INVALID_ARGUMENT, "aspect 1 for 4:3", "aspect");
  in.anamorphic = 1;
  expect(sc_pipeline_frame(p, &in, &out), SC_OK, "anamorphic viewport", NULL);
  in.anamorphic = 0;
  in.width = 64, in.height = 48;
  expect(sc_pipeline_frame(p, NULL, &out), SC_INVALID_ARGUMENT, "frame(NULL input)", "input");
  expect(sc_pipeline_frame(p, &in, NULL), SC_INVALID_ARGUMENT, "frame(NULL out)", "out");
  in.view[0] = NAN;
  expect(sc_pipeline_frame(p, &in, &out), SC_INVALID_ARGUMENT, "NaN view", "input.view");
  in.view[0] = 1.0;

  /* Mesh upload: stride 0, an index out of range, NULL arrays. */
  float pos[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}};
  uint32_t idx[6] = {0, 2, 1, 0, 3, 2};
  sc_mesh_desc m = {sizeof m, SC_F32, 0, 4, pos, SC_U32, 6, idx};
  sc_mesh mesh = 0;
  expect(sc_mesh_create(p, &m, &mesh), SC_INVALID_ARGUMENT, "stride 0", "position_stride");
  m.position_stride = sizeof pos[0];
  idx[4] = 9;
  expect(sc_mesh_create(p, &m, &mesh), SC_INVALID_ARGUMENT, "index 9 of 4 vertices", NULL);
  idx[4] = 3;
  m.positions = NULL;
  expect(sc_mesh_create(p, &m, &mesh), SC_INVALID_ARGUMENT, "NULL positions", "positions");
  m.positions = pos;
  expect(sc_mesh_create(p, NULL, &mesh), SC_INVALID_ARGUMENT, "NULL desc", "mesh");
  expect(sc_mesh_create(p, &m, &mesh), SC_OK, "mesh", NULL);

  /* Objects: NaN matrix, NULL matrix, handles of the wrong kind, stale
   * handles, double destroy. */
  double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
  sc_object obj = 0;
  id[3] = NAN;
  expect(sc_object_create(p, mesh, id, SC_FLAGS_ALL, &obj), SC_INVALID_ARGUMENT, "NaN matrix",
         "world_from_local");
  id[3] = 0.0;
  expect(sc_object_create(p, mesh, NULL, SC_FLAGS_ALL, &obj), SC_INVALID_ARGUMENT,
         "NULL matrix", "world_from_local");
  expect(sc_object_create(p, 999, id, SC_FLAGS_ALL, &obj), SC_INVALID_ARGUMENT, "unknown mesh",
         NULL);
  expect(sc_object_create(p, mesh, id, SC_FLAGS_ALL, &obj), SC_OK, "object", NULL);
  expect(sc_mesh_destroy(p, mesh), SC_INVALID_ARGUMENT, "mesh in use", NULL);
  expect(sc_object_destroy(p, mesh), SC_INVALID_ARGUMENT, "a mesh's handle for an object",
         "not an object's");
  expect(sc_mesh_destroy(p, obj), SC_INVALID_ARGUMENT, "an object's handle for a mesh",
         "not a mesh's");
  expect(sc_object_destroy(p, obj), SC_OK, "destroy object", NULL);
  expect(sc_object_destroy(p, obj), SC_INVALID_ARGUMENT, "double destroy", NULL);
  expect(sc_object_set_transform(p, obj, id), SC_INVALID_ARGUMENT, "stale object", NULL);
  expect(sc_object_destroy(p, 0), SC_OK, "destroy the null object", NULL);

  /* Lights. */
  sc_light_desc bad = {sizeof bad, 7};
  sc_light light = 0;
  expect(sc_light_create(p, &bad, &light), SC_INVALID_ARGUMENT, "light kind 7", "kind");
  sc_light_desc zero = {sizeof zero, SC_LIGHT_DIRECTIONAL};
  expect(sc_light_create(p, &zero, &light), SC_INVALID_ARGUMENT, "zero direction", NULL);

  /* Pipelines: stale and double destroy, the null handle. */
  expect(sc_pipeline_destroy(p), SC_OK, "destroy", NULL);
  expect(sc_pipeline_destroy(p), SC_INVALID_ARGUMENT, "double destroy", "stale");
  expect(sc_pipeline_frame(p, &in, &out), SC_INVALID_ARGUMENT, "frame on a destroyed pipeline",
         "stale");
  expect(sc_pipeline_destroy(0), SC_OK, "destroy the null pipeline", NULL);
  expect(sc_pipeline_create_from_file(&o, "/nonexistent/scene.gltf", &q), SC_IO, "missing file",
         "scene.gltf");
  if (failures) {
    fprintf(stderr, "misuse: %d failures\n", failures);
    return 1;
  }
  printf("misuse: ok\n");
  return 0;
}
