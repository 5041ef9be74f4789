// Prints statistics of an image for tests/report_browser_check.sh:
//   "width height grey_stddev distinct_colours non_white_fraction"
// distinct colours are counted after quantising each channel to 5 bits.
// Exit 1 when the image cannot be read.
#include <cstdio>
#include <unordered_set>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s IMAGE.png\n", argv[0]);
    return 2;
  }
  const cv::Mat bgr = cv::imread(argv[1], cv::IMREAD_COLOR);
  if (bgr.empty()) {
    std::fprintf(stderr, "cannot read %s\n", argv[1]);
    return 1;
  }
  cv::Mat grey;
  cv::cvtColor(bgr, grey, cv::COLOR_BGR2GRAY);
  cv::Scalar mean, stddev;
  cv::meanStdDev(grey, mean, stddev);
  std::unordered_set<int> colours;
  long non_white = 0;
  for (int v = 0; v < bgr.rows; ++v)
    for (int u = 0; u < bgr.cols; ++u) {
      const cv::Vec3b c = bgr.at<cv::Vec3b>(v, u);
      colours.insert(((c[0] >> 3) << 10) | ((c[1] >> 3) << 5) | (c[2] >> 3));
      if (c[0] < 245 || c[1] < 245 || c[2] < 245) ++non_white;
    }
  std::printf("%d %d %.3f %zu %.4f\n", bgr.cols, bgr.rows, stddev[0], colours.size(),
              static_cast<double>(non_white) / (static_cast<double>(bgr.total())));
  return 0;
}
