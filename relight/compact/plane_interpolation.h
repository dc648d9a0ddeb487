#pragma once
// How relight (cnr-isti-vclab) and OpenLIME interpolate PCA planes between the lights
// (relight/compact/plane_field.h): Gaussian RBF weights of the lights ("rbf"), or bilinear weights
// of an octahedral grid of directions resampled from the lights ("bilinear").
#include <Eigen/Core>
#include <vector>

namespace ls::relight::openlime {

// relight's RBF weights of the lights at a direction: Gaussian in chord distance, normalised,
// those at or below `drop` left out and the rest normalised again.
Eigen::VectorXd rbf_weights(const std::vector<Eigen::Vector3d>& lights, const Eigen::Vector3d& dir,
                            double sigma, double drop);

// The four grid nodes (index x + y * res) around a direction and their bilinear weights
// (OpenLIME's bln).
void bilinear_nodes(const Eigen::Vector3d& dir, int res, int node[4], double weight[4]);

// The light as OpenLIME takes it: (x, y) within the unit disc, z from them.
Eigen::Vector3d viewer_light(const Eigen::Vector3d& dir);

// The grid's values from the lights' (res^2 x lights), as relight's bilinear builder resamples:
// an RBF prior B corrected so that bilinear interpolation A of the grid reproduces the lights,
// iA = B + (A^T A + k I)^-1 A^T (I - A B).
Eigen::MatrixXd bilinear_resampling(const std::vector<Eigen::Vector3d>& lights, int res,
                                    double sigma, double k);

}  // namespace ls::relight::openlime
