// Notation of mechanism_sim's core, after the seed lecture (shared/seed, lecture 50,
// following appendix 8.3.2 of "Multibody Dynamics (1)", Corona Publishing).
//
// | code        | seed            | meaning                                                        |
// |-------------|-----------------|----------------------------------------------------------------|
// | r_i         | r^i             | position of body i's reference point (its centre of mass), O   |
// | p_i         | p^i             | unit Euler parameters (w, x, y, z) of body i                   |
// | A_Oi        | A^{Oi}          | rotation matrix, body-i components -> global components        |
// | A_ij        | A^{ij}          | (A_Oi)^T A_Oj                                                  |
// | v_i         | r_dot^i         | velocity of r_i, global components                             |
// | w_i         | omega'^i        | angular velocity of body i, body-i components                  |
// | dtheta_i    | delta theta'^Oi | virtual rotation of body i, body-i components                  |
// | sp_iB       | s'^B_i          | joint point B_i on body i, body-i components                   |
// | bxp_i ..    | b'^i_x ..       | joint frame unit vectors fixed in body i, body-i components    |
// | bx_i ..     | b^i_x ..        | the same in global components (A_Oi * bxp_i)                   |
// | d_ij        | d^{ij}          | B_i -> B_j = r_j + A_Oj sp_jB - r_i - A_Oi sp_iB               |
// | tilde(a)    | a~              | skew matrix, tilde(a) * b = a x b                              |
// | Phi         | C               | constraint violation (position level)                          |
// | Phi_q       | dC/d(r, theta') | constraint Jacobian: the coefficients of the variation delta C |
// | gamma       |                 | acceleration right-hand side: Phi_q * a = gamma                |
// | lambda      | lambda          | Lagrange multipliers; reaction generalized force = -Phi_q^T lambda |
// | alpha       | alpha           | screw lead per radian                                          |
// | phi         | phi             | rotation of body j relative to body i about bz_i               |
//
// Generalized coordinates of a body are (r_i, p_i); its velocity and variation
// coordinates are (v_i, w_i) and (delta r_i, dtheta_i): six per body, in that order.
// A Jacobian row of a two-body constraint is 12 wide: [r_i, theta'_i, r_j, theta'_j].
//
// Accelerations a = (v_dot, w_dot). For any constraint Phi(q) = 0,
//   Phi_ddot = Phi_q a + (d/dt Phi_q) v  =>  Phi_q a = gamma,  gamma = -(d/dt Phi_q) v.
// Each quantity carries its "centripetal" part: for a body-fixed vector a = A_Oi a',
//   a_dot = A_Oi (w x a'),  a_ddot = A_Oi (w_dot x a') + A_Oi (w x (w x a')),
// and the second term (a_cen) is what enters gamma.
//
// Joint coordinates, in both formulations (Joint::coordinates, joint.h):
//
// | code        | meaning                                                                    |
// |-------------|----------------------------------------------------------------------------|
// | x, u        | absolute coordinates of the moving bodies: x = (r_i, p_i), u = (v_i, w_i)  |
// |             | (State::x, State::u): the seed's q, so named where q is joint coordinates  |
// | Phi_x       | Phi_q, written so where q means joint coordinates (Jacobian on x)          |
// | q_k         | joint coordinate k of a joint: an angle, a slide (a spherical joint's      |
// |             | rates are its relative angular velocity in frame i)                        |
// | q_x,k       | coordinate k's row on the bodies' velocities (Row::J, 12 wide):            |
// |             | q_dot_k = q_x,k u, q_ddot_k = q_x,k a - gamma_k; an effort tau_k along it  |
// |             | acts on the bodies as q_x,k^T tau_k                                        |
// | tau         | generalized efforts along joint coordinates (applied, damping -c q_dot,    |
// |             | friction)                                                                  |
// | P           | constrained inverse mass: the accelerations a force causes with every      |
// |             | constraint held (the factored KKT matrix applied to it)                    |
//
// The joint formulation (joint_space/; Featherstone, "Rigid Body Dynamics Algorithms"
// (RBDA), 2008): the spanning tree moves in joint coordinates, the rest are closures.
//
// | code        | meaning                                                                    |
// |-------------|----------------------------------------------------------------------------|
// | q, q_dot,   | the tree's coordinates (every link's, a free body's r and p), their rates  |
// |   q_ddot    | and accelerations (State::q, qdot, qddot; nq and nv of them)               |
// | X, E, rho   | Plucker transform parent -> link, X = [E 0; -E rho~ E] (RBDA ch. 2)        |
// | S_k         | motion subspace of link k's joint (6 x nv): the joint's spatial velocity   |
// |             | is S_k q_dot_k, in the link's centre-of-mass coordinates (RBDA ch. 4)      |
// | v, a, f     | a link's spatial velocity, acceleration, and the force its joint transmits |
// | c, c_J      | velocity-product acceleration; the joint's bias S_dot q_dot                |
// | IA, pA      | articulated inertia and articulated bias force (RBDA 7.3)                  |
// | U, D, u     | U = IA S, D = S^T IA S, u = tau - S^T pA (RBDA table 7.1)                  |
// | Ic          | composite rigid-body inertia (CRBA, RBDA 6.2)                              |
// | M, h        | joint-space mass matrix and bias forces: M q_ddot + h = tau (RBDA's H and  |
// |             | C; formed only by jointSpaceInertia, the articulated passes apply M^-1)    |
// | J(q)        | the tree's Jacobian: the bodies' velocities u = J(q) q_dot                 |
// | G           | the closures' Jacobian on q, G = Phi_x J(q) (m x nv): one row per closure  |
// |             | row (cut joints, couplers, drives, limits the tree does not hold). G means |
// |             | this and nothing else in the core                                          |
// | gamma_q     | the closures' acceleration right-hand side: G q_ddot = gamma_q, gamma_q =  |
// |             | gamma - Phi_x (J_dot q_dot)                                                |
// | nu          | their velocity right-hand side: G q_dot = nu (drives: f_dot)               |
// | lambda      | closure multipliers, the absolute formulation's for the same rows:         |
// |             | M q_ddot + h = tau - G^T lambda                                            |
// | q_ddot_free | the tree's accelerations without the closures' forces                      |
// | A = G M^-1 G^T | the closure matrix: A lambda = G q_ddot_free - gamma_q (RBDA 8.3)       |
// | Z           | M^-1 G^T (or a factor's columns L^-T G^T), from inverse-mass passes        |
// | R           | a branch passage's reduced rows: the closure rows with the directions      |
// |             | held by the motion taken out (branch_passage.cpp)                          |
#pragma once
