// The window kernels' common driver, included by voxelize_window_avx2.cpp and
// voxelize_window_avx512.cpp inside their anonymous namespace, after their own FloatTests,
// float_tests, window_centres, plane_masks and edge_masks for the vector type `Vec`, with
// KILN_WINDOW_ENTRY giving the function its target. Each axis' edge masks are formed once per
// pair of windows along the two other axes and shared by every window of that pair; each window
// then ANDs its plane masks with its three pairs'.
template <class Vec>
KILN_WINDOW_ENTRY void window_masks(const WindowJob& job, WindowMasks* out) {
  FloatTests f;
  float_tests(job, f);
  Vec cen[3][kWindowsPerAxis];
  for (int a = 0; a < 3; ++a)
    for (unsigned k = 0; k < job.windows[a]; ++k)
      cen[a][k] = window_centres(float(job.base[a] + 4 * k), job.s[a]);
  WindowMasks edges[3][kWindowsPerAxis][kWindowsPerAxis];  // per axis i and window pair (k_p, k_q)
  for (int i = 0; i < 3; ++i) {
    const int p = (i + 1) % 3, q = (i + 2) % 3;
    for (unsigned kp = 0; kp < job.windows[p]; ++kp)
      for (unsigned kq = 0; kq < job.windows[q]; ++kq)
        edges[i][kp][kq] = edge_masks(f, cen[p][kp], cen[q][kq], i);
  }
  for (unsigned kz = 0; kz < job.windows[2]; ++kz)
    for (unsigned ky = 0; ky < job.windows[1]; ++ky)
      for (unsigned kx = 0; kx < job.windows[0]; ++kx) {
        const Vec c[3] = {cen[0][kx], cen[1][ky], cen[2][kz]};
        WindowMasks m = plane_masks(f, c);
        const WindowMasks* e[3] = {&edges[0][ky][kz], &edges[1][kz][kx], &edges[2][kx][ky]};
        for (const WindowMasks* x : e) m.maybe &= x->maybe, m.sure &= x->sure;
        out[kx + kWindowsPerAxis * (ky + kWindowsPerAxis * kz)] = m;
      }
}
