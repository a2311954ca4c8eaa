// Pose-graph optimizer: MRPT's sparse Levenberg-Marquardt (SPA) on the 3D pose graph.
#include <mrpt/core/initializer.h>
#include <mrpt/graphslam/levmarq.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/map/registration.h>

#include <chrono>

namespace rasterslam
{
class LevMarqOptimizer : public Optimizer
{
	DEFINE_MRPT_OBJECT(LevMarqOptimizer, rasterslam)

   public:
	/** MRPT's SPA has no robust loss: `uncertain` edges are weighted like the others. */
	OptimizerResult optimize(mrpt::graphs::CNetworkOfPoses3DInf& graph, const EdgeSet& uncertain,
	                         const std::set<mrpt::graphs::TNodeID>& fixed) override;

   protected:
	void initializeImpl(ParamReader& p) override
	{
		maxIterations_ = p.getInt("max_iterations", maxIterations_);
		initialLambda_ = p.getDouble("initial_lambda", initialLambda_);
		tau_ = p.getDouble("tau", tau_);
		e1_ = p.getDouble("e1", e1_);
		e2_ = p.getDouble("e2", e2_);
		p.requireAtLeast(maxIterations_, 1, "max_iterations");
		p.requireAtLeast(initialLambda_, 0, "initial_lambda");  // 0: chosen from tau
		p.requirePositive(tau_, "tau");
		p.requireAtLeast(e1_, 0, "e1");
		p.requireAtLeast(e2_, 0, "e2");
	}

   private:
	int maxIterations_ = 100;
	double initialLambda_ = 0, tau_ = 1e-3, e1_ = 1e-6, e2_ = 1e-6;
};
}  // namespace rasterslam

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(LevMarqOptimizer, Optimizer, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_levmarq)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::LevMarqOptimizer));
}

OptimizerResult LevMarqOptimizer::optimize(mrpt::graphs::CNetworkOfPoses3DInf& graph,
                                           const EdgeSet& /*uncertain*/,
                                           const std::set<mrpt::graphs::TNodeID>& fixed)
{
	OptimizerResult r;
	if (graph.edges.empty() || graph.nodes.size() < 2)
		return r;
	const auto t0 = std::chrono::steady_clock::now();
	mrpt::containers::yaml params = mrpt::containers::yaml::Map();
	params["max_iterations"] = maxIterations_;
	params["initial_lambda"] = initialLambda_;
	params["tau"] = tau_;
	params["e1"] = e1_;
	params["e2"] = e2_;
	mrpt::graphslam::TResultInfoSpaLevMarq info;
	r.initialError = graph.chi2();
	// MRPT keeps the root fixed unless given the nodes to optimize: with fixed nodes (an
	// earlier session's keyframes) they hold the graph, and the root moves too.
	std::set<mrpt::graphs::TNodeID> free;
	for (const auto& [id, p] : graph.nodes)
		if (!fixed.count(id))
			free.insert(id);
	mrpt::graphslam::optimize_graph_spa_levmarq(graph, info, fixed.empty() ? nullptr : &free,
	                                            params);
	r.ran = true;
	r.iterations = info.num_iters;
	r.finalError = graph.chi2();
	r.time_ms =
	    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	return r;
}
