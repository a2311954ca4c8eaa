// Pose-graph optimizer: Ceres Solver with a robust loss on the edges that may be wrong.
#include <ceres/ceres.h>
#include <ceres/rotation.h>
#include <mrpt/core/initializer.h>
#include <rasterslam/core/plugin.h>
#include <rasterslam/map/registration.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace rasterslam
{
class CeresOptimizer : public Optimizer
{
	DEFINE_MRPT_OBJECT(CeresOptimizer, rasterslam)

   public:
	/** Edges in `uncertain` get the robust loss (`loss`, `loss_scale`); the others none. */
	OptimizerResult optimize(mrpt::graphs::CNetworkOfPoses3DInf& graph, const EdgeSet& uncertain,
	                         const std::set<mrpt::graphs::TNodeID>& fixed) override;

   protected:
	void initializeImpl(ParamReader& p) override
	{
		loss_ = p.getChoice("loss", loss_, {"cauchy", "huber", "none"});
		lossScale_ = p.getDouble("loss_scale", lossScale_);
		p.requirePositive(lossScale_, "loss_scale");
		maxIterations_ = p.getInt("max_iterations", maxIterations_);
		p.requireAtLeast(maxIterations_, 1, "max_iterations");
		functionTolerance_ = p.getDouble("function_tolerance", functionTolerance_);
		// Ceres accepts 0 (never stop on the cost's relative change) but rejects negatives.
		p.requireAtLeast(functionTolerance_, 0, "function_tolerance");
	}

   private:
	std::string loss_ = "cauchy";
	double lossScale_ = 3.0;
	int maxIterations_ = 50;
	double functionTolerance_ = 1e-8;
};
}  // namespace rasterslam

using namespace rasterslam;

IMPLEMENTS_MRPT_OBJECT(CeresOptimizer, Optimizer, rasterslam)

RASTERSLAM_REGISTER_CLASSES(register_rasterslam_plugin_ceres)
{
	mrpt::rtti::registerClass(CLASS_ID(rasterslam::CeresOptimizer));
}

namespace
{
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using TNodeID = mrpt::graphs::TNodeID;

/** A node's pose as Ceres sees it: translation and a unit quaternion in Eigen's memory order
 *  (x, y, z, w), which is what ceres::EigenQuaternionManifold expects. */
struct NodeBlock
{
	double t[3];
	double q[4];
	bool fixed = false;
};

std::string edgeName(TNodeID from, TNodeID to)
{
	return "edge " + std::to_string(from) + "->" + std::to_string(to);
}

/** S with S^T S = info, so that |S e|^2 = e^T info e. LLT when info is positive definite;
 *  a positive semi-definite info (an axis the sensor does not observe) goes through LDLT,
 *  S = sqrt(D) L^T P, which leaves that axis unweighted instead of failing. */
Matrix6d sqrtInformation(const Matrix6d& infoIn, TNodeID from, TNodeID to)
{
	if (!infoIn.allFinite())
		throw std::runtime_error("CeresOptimizer: " + edgeName(from, to) +
		                         " has a non-finite information matrix");
	const Matrix6d info = 0.5 * (infoIn + infoIn.transpose());
	const Eigen::LLT<Matrix6d> llt(info);
	if (llt.info() == Eigen::Success)
		return llt.matrixU();
	const Eigen::LDLT<Matrix6d> ldlt(info);
	const Eigen::Matrix<double, 6, 1> d = ldlt.vectorD();
	const double tol = 1e-9 * std::max(1.0, d.cwiseAbs().maxCoeff());
	if (ldlt.info() != Eigen::Success || d.minCoeff() < -tol)
		throw std::runtime_error("CeresOptimizer: " + edgeName(from, to) +
		                         " has an information matrix that is not positive semi-definite");
	const Eigen::Matrix<double, 6, 1> sqrtD = d.cwiseMax(0.0).cwiseSqrt();
	const Matrix6d S = sqrtD.asDiagonal() * Matrix6d(ldlt.matrixU());
	// LDLT factors P info P^T = L D L^T: undo the pivoting on the columns.
	return S * ldlt.transpositionsP();
}

/** Whitened error of one edge. With E = T_meas^-1 * T_from^-1 * T_to, the error is
 *  [t(E); rotation vector of R(E)] as in MRPT's SPA (SE(3) pseudo-log), but with the rotation
 *  vector read as (z, y, x): for small angles those are yaw, pitch and roll, the order of
 *  MRPT's information matrices (x y z yaw pitch roll). */
struct EdgeError
{
	EdgeError(const mrpt::poses::CPose3D& meas, const Matrix6d& sqrtInfo) : sqrtInfo_(sqrtInfo)
	{
		tMeas_ = Eigen::Vector3d(meas.x(), meas.y(), meas.z());
		qMeasInv_ = Eigen::Quaterniond(meas.getRotationMatrix().asEigen()).normalized().conjugate();
	}

	template <typename T>
	bool operator()(const T* tFrom, const T* qFrom, const T* tTo, const T* qTo, T* residual) const
	{
		const Eigen::Map<const Eigen::Matrix<T, 3, 1>> pa(tFrom), pb(tTo);
		const Eigen::Map<const Eigen::Quaternion<T>> qa(qFrom), qb(qTo);
		const Eigen::Quaternion<T> qaInv = qa.conjugate();
		const Eigen::Quaternion<T> qMeasInv = qMeasInv_.cast<T>();
		// T_from^-1 * T_to, then T_meas^-1 times that.
		const Eigen::Quaternion<T> qe = qMeasInv * (qaInv * qb);
		const Eigen::Matrix<T, 3, 1> te = qMeasInv * (qaInv * (pb - pa) - tMeas_.cast<T>());
		// QuaternionToAngleAxis takes (w, x, y, z) and returns the shortest rotation, so q and
		// -q give the same error.
		const T qwxyz[4] = {qe.w(), qe.x(), qe.y(), qe.z()};
		T aa[3];
		ceres::QuaternionToAngleAxis(qwxyz, aa);
		Eigen::Matrix<T, 6, 1> e;
		e << te, aa[2], aa[1], aa[0];
		Eigen::Map<Eigen::Matrix<T, 6, 1>> r(residual);
		r = sqrtInfo_.cast<T>() * e;
		return true;
	}

	Eigen::Vector3d tMeas_;
	Eigen::Quaterniond qMeasInv_;
	Matrix6d sqrtInfo_;
};

struct EdgeTerm
{
	TNodeID from, to;
	EdgeError error;
	bool uncertain;
};

/** Squared whitened residual of an edge at the current block values (no loss). */
double squaredError(const EdgeTerm& e, const std::map<TNodeID, NodeBlock>& blocks)
{
	const NodeBlock& a = blocks.at(e.from);
	const NodeBlock& b = blocks.at(e.to);
	double r[6];
	e.error(a.t, a.q, b.t, b.q, r);
	double s = 0;
	for (double v : r)
		s += v * v;
	return s;
}

/** Smallest node id of each connected component (edges taken as undirected). */
std::map<TNodeID, TNodeID> componentRoots(const std::map<TNodeID, NodeBlock>& blocks,
                                          const std::vector<EdgeTerm>& edges)
{
	std::map<TNodeID, TNodeID> parent;
	for (const auto& kv : blocks)
		parent[kv.first] = kv.first;
	const auto find = [&](TNodeID x)
	{
		while (parent[x] != x)
			x = parent[x] = parent[parent[x]];
		return x;
	};
	for (const auto& e : edges)
	{
		const TNodeID a = find(e.from), b = find(e.to);
		// Keeping the smaller id as the representative makes it the component's first node.
		if (a != b)
			parent[std::max(a, b)] = std::min(a, b);
	}
	std::map<TNodeID, TNodeID> root;
	for (const auto& kv : blocks)
		root[kv.first] = find(kv.first);
	return root;
}
}  // namespace

OptimizerResult CeresOptimizer::optimize(mrpt::graphs::CNetworkOfPoses3DInf& graph,
                                         const EdgeSet& uncertain,
                                         const std::set<mrpt::graphs::TNodeID>& fixed)
{
	OptimizerResult r;
	if (graph.edges.empty() || graph.nodes.size() < 2)
		return r;
	const auto t0 = std::chrono::steady_clock::now();

	std::map<TNodeID, NodeBlock> blocks;
	std::vector<EdgeTerm> edges;
	edges.reserve(graph.edges.size());
	for (const auto& kv : graph.edges)
	{
		const auto [from, to] = kv.first;
		for (TNodeID id : {from, to})
		{
			if (blocks.count(id))
				continue;
			const auto it = graph.nodes.find(id);
			if (it == graph.nodes.end())
				throw std::runtime_error("CeresOptimizer: " + edgeName(from, to) + " names node " +
				                         std::to_string(id) + ", which has no pose in the graph");
			NodeBlock& b = blocks[id];
			const Eigen::Quaterniond q =
			    Eigen::Quaterniond(it->second.getRotationMatrix().asEigen()).normalized();
			b.t[0] = it->second.x();
			b.t[1] = it->second.y();
			b.t[2] = it->second.z();
			b.q[0] = q.x();
			b.q[1] = q.y();
			b.q[2] = q.z();
			b.q[3] = q.w();
		}
		edges.push_back(
		    {from, to,
		     EdgeError(kv.second.mean, sqrtInformation(kv.second.cov_inv.asEigen(), from, to)),
		     uncertain.count(kv.first) > 0});
	}

	// A component not linked to the root by any edge can move as a whole without changing the
	// error (6 free directions). Fixing its first node removes that freedom, so the normal
	// equations stay positive definite and the component stays where the odometry put it,
	// instead of relying on the damping to hold it.
	// A component that holds a fixed node (an earlier session's keyframe) is held by it: its
	// root then moves too (the session's first pose came from one relocalization). Otherwise
	// the root holds its component.
	const auto compRoot = componentRoots(blocks, edges);
	std::set<TNodeID> heldComponents;
	for (const auto& [id, b] : blocks)
		if (fixed.count(id))
			heldComponents.insert(compRoot.at(id));
	const bool rootFixed =
	    blocks.count(graph.root) && !heldComponents.count(compRoot.at(graph.root));
	if (rootFixed)
		heldComponents.insert(compRoot.at(graph.root));
	for (auto& [id, b] : blocks)
		b.fixed = (id == graph.root && rootFixed) || fixed.count(id) > 0 ||
		          (compRoot.at(id) == id && !heldComponents.count(id));

	std::unique_ptr<ceres::LossFunction> loss;
	if (loss_ == "cauchy")
		loss = std::make_unique<ceres::CauchyLoss>(lossScale_);
	else if (loss_ == "huber")
		loss = std::make_unique<ceres::HuberLoss>(lossScale_);
	auto manifold = std::make_unique<ceres::EigenQuaternionManifold>();

	ceres::Problem::Options po;
	// One loss and one manifold shared by many blocks: owned here, not by the problem.
	po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
	po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
	ceres::Problem problem(po);
	for (auto& [id, b] : blocks)
	{
		problem.AddParameterBlock(b.t, 3);
		problem.AddParameterBlock(b.q, 4, manifold.get());
		if (b.fixed)
		{
			problem.SetParameterBlockConstant(b.t);
			problem.SetParameterBlockConstant(b.q);
		}
	}
	for (const auto& e : edges)
	{
		// A self-edge has a constant error (it only counts in chi2), and Ceres refuses a
		// residual that names the same block twice.
		if (e.from == e.to)
			continue;
		NodeBlock& a = blocks.at(e.from);
		NodeBlock& b = blocks.at(e.to);
		problem.AddResidualBlock(
		    new ceres::AutoDiffCostFunction<EdgeError, 6, 3, 4, 3, 4>(new EdgeError(e.error)),
		    e.uncertain ? loss.get() : nullptr, a.t, a.q, b.t, b.q);
	}

	double chi2 = 0;
	for (const auto& e : edges)
		chi2 += squaredError(e, blocks);
	r.initialError = chi2;
	if (problem.NumResidualBlocks() == 0)
		return r;

	ceres::Solver::Options so;
	so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
	so.max_num_iterations = maxIterations_;
	so.function_tolerance = functionTolerance_;
	// Single-threaded so that two runs on the same graph give the same poses.
	so.num_threads = 1;
	so.minimizer_progress_to_stdout = false;
	so.logging_type = ceres::SILENT;
	ceres::Solver::Summary summary;
	ceres::Solve(so, &problem, &summary);
	r.iterations = summary.iterations.size();
	if (!summary.IsSolutionUsable())
	{
		MRPT_LOG_WARN_STREAM("CeresOptimizer: no usable solution: " << summary.message);
		r.finalError = r.initialError;
		return r;
	}
	r.ran = true;

	chi2 = 0;
	for (const auto& e : edges)
	{
		const double s = squaredError(e, blocks);
		chi2 += s;
		if (!loss || !e.uncertain)
			continue;
		// rho'(s): the factor the loss put on this edge's squared error at the solution. For
		// several edges with the same (from, to), the smallest (the most doubted) is kept.
		double rho[3];
		loss->Evaluate(s, rho);
		const auto key = std::make_pair(e.from, e.to);
		auto [it, inserted] = r.edgeWeights.emplace(key, rho[1]);
		if (!inserted)
			it->second = std::min(it->second, rho[1]);
	}
	r.finalError = chi2;

	for (const auto& [id, b] : blocks)
	{
		// Fixed nodes are not written back: the quaternion round trip would change their
		// last bits, and the root must stay exactly where it was.
		if (b.fixed)
			continue;
		const Eigen::Quaterniond q(b.q[3], b.q[0], b.q[1], b.q[2]);
		mrpt::math::CMatrixDouble33 R(q.normalized().toRotationMatrix());
		graph.nodes[id] =
		    mrpt::poses::CPose3D(R, mrpt::math::CVectorFixedDouble<3>({b.t[0], b.t[1], b.t[2]}));
	}
	r.time_ms =
	    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
	return r;
}
