/* What a gather costs on this CPU, against loading the same values other ways: the question
 * behind the mesh cloth's packed state (src/mesh_cloth/packed.rs, docs/mesh_cloth.md, "The
 * explicit force pass").
 *
 *     gcc -O2 -mavx2 -mavx512f -mfma benches/gather_cost.c -o /tmp/gather_cost && /tmp/gather_cost
 *
 * 200,000 slots (the 16k mesh's), each loading six coordinates of a vertex near its own
 * (indices within 100 of slot / 12, as a locally numbered mesh's), from 16,384 vertices:
 *   gather256  six 8-wide vgatherdps a row of 8 slots, from six arrays;
 *   scalar     the same values by eight scalar loads and inserts a coordinate (what LLVM's AVX2
 *              build of the pass did);
 *   packed     one 32-byte load a slot of the vertex's packed line [x, y, z, vx, vy, vz, 0, 0]
 *              (no transpose);
 *   gather512  six 16-wide vgatherdps a row of 16 slots.
 * Prints ms per pass of all the slots, best of nothing: three rounds, read them side by side. */
#include <immintrin.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#define N 16384
#define M 200000
#define PASSES 20
static double now(void) {
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return t.tv_sec + t.tv_nsec * 1e-9;
}
static float X[6][N];
static int idx[M];
static float packed[N][8] __attribute__((aligned(32)));
int main(void) {
  for (int c = 0; c < 6; c++)
    for (int i = 0; i < N; i++) X[c][i] = i * 0.001f + c;
  for (int i = 0; i < N; i++)
    for (int c = 0; c < 8; c++) packed[i][c] = c < 6 ? X[c][i] : 0.0f;
  for (int i = 0; i < M; i++) idx[i] = (i / 12 + rand() % 200 - 100 + N) % N;
  for (int round = 0; round < 3; round++) {
    double t = now();
    __m256 a8 = _mm256_setzero_ps();
    for (int p = 0; p < PASSES; p++)
      for (int r = 0; r < M; r += 8) {
        __m256i j = _mm256_loadu_si256((const __m256i *)(idx + r));
        for (int c = 0; c < 6; c++) a8 = _mm256_add_ps(a8, _mm256_i32gather_ps(X[c], j, 4));
      }
    double gather256 = (now() - t) / PASSES;
    t = now();
    __m256 s8 = _mm256_setzero_ps();
    for (int p = 0; p < PASSES; p++)
      for (int r = 0; r < M; r += 8) {
        const int *j = idx + r;
        for (int c = 0; c < 6; c++) {
          const float *x = X[c];
          s8 = _mm256_add_ps(s8, _mm256_setr_ps(x[j[0]], x[j[1]], x[j[2]], x[j[3]], x[j[4]],
                                                x[j[5]], x[j[6]], x[j[7]]));
        }
      }
    double scalar = (now() - t) / PASSES;
    t = now();
    __m256 l8[8];
    for (int l = 0; l < 8; l++) l8[l] = _mm256_setzero_ps();
    for (int p = 0; p < PASSES; p++)
      for (int r = 0; r < M; r += 8)
        for (int l = 0; l < 8; l++) l8[l] = _mm256_add_ps(l8[l], _mm256_load_ps(packed[idx[r + l]]));
    double loads = (now() - t) / PASSES;
    t = now();
    __m512 a16 = _mm512_setzero_ps();
    for (int p = 0; p < PASSES; p++)
      for (int r = 0; r < M; r += 16) {
        __m512i j = _mm512_loadu_si512((const void *)(idx + r));
        for (int c = 0; c < 6; c++) a16 = _mm512_add_ps(a16, _mm512_i32gather_ps(j, X[c], 4));
      }
    double gather512 = (now() - t) / PASSES;
    float sink[16];
    _mm256_storeu_ps(sink, _mm256_add_ps(_mm256_add_ps(a8, s8), l8[0]));
    _mm512_storeu_ps(sink, _mm512_add_ps(a16, _mm512_set1_ps(sink[0])));
    printf("ms a pass of %d slots x 6: gather256 %.3f  scalar %.3f  packed %.3f  gather512 %.3f"
           "  (%.1f / %.1f ns a gather)  [%g]\n",
           M, gather256 * 1e3, scalar * 1e3, loads * 1e3, gather512 * 1e3,
           gather256 * 1e9 / (6.0 * M / 8), gather512 * 1e9 / (6.0 * M / 16), sink[0]);
  }
  return 0;
}
