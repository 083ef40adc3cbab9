"""The deep cyber player: a Q-network avatar and its DQN training (METHODS section 8).

`network` is the compiled fully connected network (values, gradient, Adam); `features` turns
an avatar's view of its neighbours into the network's input ("dynamic input"); `player` is the
avatar that plays with it (`DeepCyberPlayer`, model files); `training` is the DQN learner
(`DQNLearner`: replay buffer, target network, exploration schedule).
"""
