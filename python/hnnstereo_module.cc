// pybind11 bindings of the library facade (<hnnstereo/hnnstereo.h>) as hnnstereo._hnnstereo;
// python/hnnstereo/__init__.py gives the Python API around them. numpy images are wrapped as
// cv::Mat without a copy; the GIL is released while matching.
#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cstdint>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>

#include "hnnstereo/hnnstereo.h"

namespace py = pybind11;

namespace {

// A numpy image (rows x cols grey, or rows x cols x 1|3|4, uint8 or uint16) as a cv::Mat header
// over its buffer; the caller keeps `array` alive. Raises ValueError with a one-line reason.
cv::Mat ImageOf(const py::array& array, const char* which) {
  const std::string name(which);
  int depth = -1;
  if (py::isinstance<py::array_t<std::uint8_t>>(array)) {
    depth = CV_8U;
  } else if (py::isinstance<py::array_t<std::uint16_t>>(array)) {
    depth = CV_16U;
  } else {
    throw std::invalid_argument(name + " image must be uint8 or uint16 (got dtype " +
                                std::string(py::str(array.dtype())) + ")");
  }
  if (array.ndim() != 2 && array.ndim() != 3) {
    throw std::invalid_argument(name + " image must be H x W (grey) or H x W x C (got " +
                                std::to_string(array.ndim()) + " dimensions)");
  }
  const int channels = array.ndim() == 3 ? static_cast<int>(array.shape(2)) : 1;
  if (channels != 1 && channels != 3 && channels != 4) {
    throw std::invalid_argument(name + " image must have 1, 3 (BGR) or 4 (BGRA) channels (got " +
                                std::to_string(channels) + ")");
  }
  if (array.shape(0) == 0 || array.shape(1) == 0) throw std::invalid_argument(name + " image is empty");
  if (!(array.flags() & py::array::c_style)) {
    throw std::invalid_argument(name + " image must be C-contiguous (use numpy.ascontiguousarray)");
  }
  return cv::Mat(static_cast<int>(array.shape(0)), static_cast<int>(array.shape(1)),
                 CV_MAKETYPE(depth, channels), const_cast<void*>(array.data()));
}

py::tuple ToPython(hnnstereo::MatchResult&& result) {
  const auto n = static_cast<py::ssize_t>(result.matches.size());
  py::array_t<float> matches({n, static_cast<py::ssize_t>(6)});
  auto out = matches.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const hnnstereo::Match& m = result.matches[static_cast<std::size_t>(i)];
    out(i, 0) = m.xl;
    out(i, 1) = m.yl;
    out(i, 2) = m.xr;
    out(i, 3) = m.yr;
    out(i, 4) = m.activation;
    out(i, 5) = m.confidence;
  }
  return py::make_tuple(matches, result.report.json, result.report.notice);
}

}  // namespace

PYBIND11_MODULE(_hnnstereo, m) {
  m.doc() = "hnnstereo: stereo matching with a Hopfield network on OpenCL (C++ bindings)";
  m.attr("__version__") = hnnstereo::Version();
  m.def("option_names", &hnnstereo::MatcherOptionNames, "Override names a Matcher accepts");
  m.def("preset_names", &hnnstereo::PresetNames, "Preset names, hnn-default first");

  py::class_<hnnstereo::Calibration>(m, "Calibration",
                                     "A stereo calibration (CAL.yml or Middlebury calib.txt), mm")
      .def_property_readonly("P1", &hnnstereo::Calibration::P1)
      .def_property_readonly("P2", &hnnstereo::Calibration::P2)
      .def_property_readonly("F", &hnnstereo::Calibration::F)
      .def_property_readonly("C1", &hnnstereo::Calibration::C1)
      .def_property_readonly("C2", &hnnstereo::Calibration::C2)
      .def_property_readonly("image_width", &hnnstereo::Calibration::image_width)
      .def_property_readonly("image_height", &hnnstereo::Calibration::image_height)
      .def_property_readonly("rectified", &hnnstereo::Calibration::rectified)
      .def_property_readonly("has_distortion", &hnnstereo::Calibration::has_distortion)
      .def("__repr__", [](const hnnstereo::Calibration& c) {
        return "<hnnstereo.Calibration " + std::to_string(c.image_width()) + "x" +
               std::to_string(c.image_height()) + (c.rectified() ? " rectified>" : ">");
      });
  m.def("load_calibration", &hnnstereo::LoadCalibration, py::arg("path"),
        "Reads a CAL.yml or a Middlebury calib.txt");

  py::class_<hnnstereo::Matcher>(m, "_Matcher")
      .def(py::init<const std::string&, const hnnstereo::MatcherOverrides&>(), py::arg("preset"),
           py::arg("overrides"))
      .def_property_readonly("preset", &hnnstereo::Matcher::preset)
      .def_property_readonly("device", &hnnstereo::Matcher::device)
      .def_property_readonly("notice", &hnnstereo::Matcher::notice)
      .def("match_rectified",
           [](hnnstereo::Matcher& matcher, const py::array& left, const py::array& right,
              double max_disparity) {
             const cv::Mat l = ImageOf(left, "left"), r = ImageOf(right, "right");
             hnnstereo::MatchResult result;
             {
               py::gil_scoped_release release;
               result = matcher.Match(l, r, max_disparity);
             }
             return ToPython(std::move(result));
           })
      .def("match_calibrated", [](hnnstereo::Matcher& matcher, const py::array& left,
                                  const py::array& right, const hnnstereo::Calibration& calib) {
        const cv::Mat l = ImageOf(left, "left"), r = ImageOf(right, "right");
        hnnstereo::MatchResult result;
        {
          py::gil_scoped_release release;
          result = matcher.Match(l, r, calib);
        }
        return ToPython(std::move(result));
      });

  m.def("sense_positions",
        [](const py::array& left, const py::array& right, const hnnstereo::Calibration& calib,
           const hnnstereo::MatcherOverrides& overrides) {
          const cv::Mat l = ImageOf(left, "left"), r = ImageOf(right, "right");
          hnnstereo::SensingResult result;
          {
            py::gil_scoped_release release;
            result = hnnstereo::SensePositions(l, r, calib, overrides);
          }
          return py::make_tuple(result.json, result.notice);
        },
        py::arg("left"), py::arg("right"), py::arg("calib"), py::arg("overrides"));
}
