// The glTF fit's two optimizers on one material, side by side (scripts/bench_gltf.sh --optimizers):
//   - Levenberg-Marquardt per texel, what `nbtf export-gltf` runs (gltf/gltf_fit.h), on all
//     threads;
//   - every texel at once with libtorch's Adam: the same BRDF (the specification's
//     metallic-roughness model, as gltf/gltf_brdf.cpp evaluates it) written in tensors, its
//     gradient by autograd, the same two starts (roughness 0.7 and 0.3) per texel, the better
//     one kept.
// Both fit the base material (no sheen, no specular) to the same sampled images at the same
// exposure. The figure of merit is the RMSE over those samples (linear, not normalized: the
// quantity both minimize) and the seconds. The torch fit's bounds are smooth maps (sigmoid,
// tanh) of free parameters; it has no peak guard (the LM fit's refits can only raise its
// sample RMSE, so the comparison favours torch there).
// Prints one "result KEY VALUE" line per figure.
#include <torch/torch.h>

#include <cmath>
#include <cstdio>
#include <cxxopts.hpp>
#include <string>
#include <vector>

#include "gltf/gltf_fit.h"
#include "io/btf_loader.h"
#include "util/error.h"
#include "util/parallel.h"
#include "util/timer.h"

namespace {
using namespace nbtf;
using torch::indexing::Slice;

constexpr double kPi = 3.14159265358979323846;

struct TorchFit {
  torch::Tensor lights, views;  // [S, 3]
  torch::Tensor values;         // [T, S, 3]
  double exposure = 1, maxSlope = 1, minRoughness = 0.1;

  // Per-texel squared error summed over the samples `pick` (all when undefined) and the
  // channels, [P] for P = starts x T texels.
  torch::Tensor costs(const torch::Tensor& raw, int starts, const torch::Tensor& pick = {}) const {
    const auto lights = pick.defined() ? this->lights.index_select(0, pick) : this->lights;
    const auto views = pick.defined() ? this->views.index_select(0, pick) : this->views;
    const auto values = pick.defined() ? this->values.index_select(1, pick) : this->values;
    const auto base = torch::sigmoid(raw.index({Slice(), Slice(0, 3)}));        // [P, 3]
    const auto metallic = torch::sigmoid(raw.index({Slice(), Slice(3, 4)}));    // [P, 1]
    const auto roughness = minRoughness + (1 - minRoughness) * torch::sigmoid(raw.index({Slice(), Slice(4, 5)}));
    const auto q = raw.index({Slice(), Slice(5, 7)});
    const auto qLen = torch::sqrt((q * q).sum(1, true) + 1e-12);
    const auto slope = q * (maxSlope * torch::tanh(qLen) / qLen);  // inside the disk of maxSlope
    auto n = torch::cat({slope, torch::ones_like(metallic)}, 1);
    n = n / n.norm(2, 1, true);                                        // [P, 3]
    const auto h = torch::nn::functional::normalize(lights + views, torch::nn::functional::NormalizeFuncOptions().dim(1));
    const auto nl = torch::matmul(n, lights.t()), nv = torch::matmul(n, views.t()), nh = torch::matmul(n, h.t());  // [P, S]
    const auto vh = (views * h).sum(1).abs();                           // [S]
    const auto schlick = torch::pow(1 - vh, 5).unsqueeze(0);            // [1, S]
    const auto alpha = torch::clamp_min(roughness * roughness, gltf::kMinAlpha);  // [P, 1]
    const auto a2 = alpha * alpha;
    const auto visible = (nl > 0) & (nv > 0);
    const auto nlc = torch::clamp_min(nl, 0), nvc = torch::clamp_min(nv, 0), nhc = torch::clamp_min(nh, 0);
    const auto d = nhc * nhc * (a2 - 1) + 1;
    const auto ggx = a2 / (kPi * d * d);
    const auto vis = 0.5 / (nvc * torch::sqrt(nlc * nlc * (1 - a2) + a2) + nlc * torch::sqrt(nvc * nvc * (1 - a2) + a2) + 1e-12);
    const auto k = torch::where(visible, exposure * nlc, torch::zeros_like(nl));  // [P, S]
    const auto spec = (k * ggx * vis).unsqueeze(2);                     // [P, S, 1]
    const auto fd = (gltf::kDielectricF0 + (1 - gltf::kDielectricF0) * schlick).unsqueeze(2);  // [1, S, 1]
    const auto b = base.unsqueeze(1), m = metallic.unsqueeze(1);       // [P, 1, 3], [P, 1, 1]
    const auto dielectric = (1 - fd) * b * (k.unsqueeze(2) / kPi) + fd * spec;
    const auto metal = spec * (b + (1 - b) * schlick.unsqueeze(2));
    const auto predicted = (1 - m) * dielectric + m * metal;            // [P, S, 3]
    const auto target = values.repeat({starts, 1, 1});
    return (predicted - target).pow(2).sum({1, 2});
  }
};

torch::Tensor logit(double p) { return torch::full({}, std::log(p / (1 - p))); }

}  // namespace

int main(int argc, char** argv) {
  cxxopts::Options cli("nbtf-bench-gltf-fit", "the glTF fit by Levenberg-Marquardt and by torch's Adam, side by side");
  cli.add_options()("stack", "an image stack", cxxopts::value<std::string>())(
      "steps", "Adam steps", cxxopts::value<int>()->default_value("500"))(
      "lr", "Adam's learning rate", cxxopts::value<double>()->default_value("0.2"))(
      "report-every", "steps between reported points", cxxopts::value<int>()->default_value("100"))(
      "batch-samples", "samples per step, drawn anew each step (0: all)", cxxopts::value<int>()->default_value("64"))(
      "seed", "sample and start seed", cxxopts::value<std::uint64_t>()->default_value("1"));
  cli.parse_positional({"stack"});
  try {
    const auto args = cli.parse(argc, argv);
    if (!args.count("stack")) throw Error("give an image stack");
    const std::string path = args["stack"].as<std::string>();
    LoadOptions load;
    load.progress = false;
    const BtfStack stack = loadBtfStack(resolveBtfInput(path, load), load);
    gltf::FitOptions options;
    options.seed = args["seed"].as<std::uint64_t>();
    options.progress = false;
    const gltf::FitData data = gltf::gatherFitData(stack.width(), stack.height(), stack.lights(), stack.views(),
                                                   [&](int image, float* rgb) { stack.imageLinear(image, rgb); }, options);
    const double exposure = gltf::chooseExposure(data);
    const std::size_t texels = static_cast<std::size_t>(data.width) * data.height, samples = data.count();
    std::printf("material %s: %zu texels, %zu samples per texel, %d threads\n", path.c_str(), texels, samples, threadCount());

    gltf::FitSummary lm;
    gltf::fitMaterial(data, exposure, options, &lm);
    std::printf("Levenberg-Marquardt: %.2f s, sample RMSE %.5f (%d texels refitted for the peak guard)\n", lm.seconds,
                lm.sampleRmse, lm.refitted);
    std::printf("result lm_seconds %.3f\nresult lm_rmse %.6f\n", lm.seconds, lm.sampleRmse);

    torch::set_num_threads(threadCount());
    torch::manual_seed(options.seed);
    TorchFit fit;
    std::vector<float> l, v;
    for (std::size_t i = 0; i < samples; ++i)
      for (int c = 0; c < 3; ++c) l.push_back(float(data.lights[i][c])), v.push_back(float(data.views[i][c]));
    fit.lights = torch::from_blob(l.data(), {long(samples), 3}).clone();
    fit.views = torch::from_blob(v.data(), {long(samples), 3}).clone();
    fit.values = torch::from_blob(const_cast<float*>(data.values.data()), {long(texels), long(samples), 3}).clone();
    fit.exposure = exposure;
    fit.maxSlope = std::tan(options.maxTiltDeg * kPi / 180);
    fit.minRoughness = options.minRoughness;
    // Two starts per texel, as the LM fit: grey dielectric, flat, roughness 0.7 and 0.3.
    const int starts = 2;
    auto raw = torch::zeros({long(starts * texels), 7});
    raw.index_put_({Slice(), Slice(3, 4)}, logit(0.02));
    const auto roughnessLogit = [&](double r) { return logit((r - fit.minRoughness) / (1 - fit.minRoughness)); };
    raw.index_put_({Slice(0, long(texels)), Slice(4, 5)}, roughnessLogit(0.7));
    raw.index_put_({Slice(long(texels), long(2 * texels)), Slice(4, 5)}, roughnessLogit(0.3));
    raw.set_requires_grad(true);
    const double lr = args["lr"].as<double>();
    torch::optim::Adam adam({raw}, torch::optim::AdamOptions(lr));  // the rate is set per step below
    const int steps = args["steps"].as<int>(), every = args["report-every"].as<int>();
    const double norm = double(texels) * samples * 3;
    const auto start = Clock::now();
    double reachedLm = -1;
    const int batch = args["batch-samples"].as<int>();
    const auto fullRmse = [&] {  // of the better start per texel, over all samples
      torch::NoGradGuard guard;
      const auto c = fit.costs(raw, starts).view({starts, long(texels)});
      return std::sqrt(std::get<0>(c.min(0)).sum().item<double>() / norm);
    };
    double measuring = 0;  // seconds spent on the full-cost checks, not counted
    for (int step = 1; step <= steps; ++step) {
      // A cosine decay to zero: a constant rate leaves the sampled gradient's noise in the result.
      for (auto& group : adam.param_groups())
        static_cast<torch::optim::AdamOptions&>(group.options()).lr(lr * 0.5 * (1 + std::cos(kPi * (step - 1) / steps)));
      adam.zero_grad();
      const auto pick = batch > 0 && batch < long(samples) ? torch::randperm(long(samples)).index({Slice(0, batch)})
                                                          : torch::Tensor();
      fit.costs(raw, starts, pick).sum().backward();
      adam.step();
      if (step % every == 0 || step == steps) {
        const double seconds = secondsSince(start) - measuring;
        const auto before = Clock::now();
        const double rmse = fullRmse();
        measuring += secondsSince(before);
        if (reachedLm < 0 && rmse <= lm.sampleRmse) reachedLm = seconds;
        std::printf("torch Adam: step %5d, %7.2f s, sample RMSE %.5f\n", step, seconds, rmse);
        if (step == steps) std::printf("result torch_seconds %.3f\nresult torch_rmse %.6f\n", seconds, rmse);
        std::fflush(stdout);
      }
    }
    std::printf("result torch_seconds_to_lm_rmse %.3f\n", reachedLm);  // -1: never reached
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "nbtf-bench-gltf-fit: %s\n", e.what());
    return 1;
  }
}
